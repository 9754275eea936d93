// Tables of constant maps at every scale of float input (env_tables.h): subnormal, smallest normal, ordinary and
// near FLT_MAX radiance must give the same tables, whose pdf is exactly 1 / (4 pi) and which draw every row.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace envkit;

namespace {

constexpr double kUniformPdf = 1.0 / (4.0 * M_PI);

struct Case {
  Kind grid;
  float value;
  std::string name;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  const std::pair<float, const char*> values[] = {{1e-42f, "subnormal_1em42"},
                                                  {1e-38f, "smallest_normal_1em38"},
                                                  {1.0f, "one"},
                                                  {0.9f * FLT_MAX, "near_float_max"}};
  for (Kind grid : {Kind::LatLong, Kind::Octahedral, Kind::HEALPix})
    for (const auto& [v, name] : values)
      out.push_back({grid, v,
                     std::string(grid == Kind::LatLong      ? "latlong_"
                                 : grid == Kind::Octahedral ? "octa_"
                                                            : "healpix_") +
                         name});
  return out;
}

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

EnvMap constant_map(Kind grid, float value) {
  EnvMap env;
  if (grid == Kind::LatLong) {
    env.param = std::make_unique<LatLongMap>(128, 64);
  } else if (grid == Kind::Octahedral) {
    env.param = std::make_unique<OctahedralMap>(64);
  } else {
    env.param = std::make_unique<HealpixMap>(16);
  }
  env.image = Image(env.param->width(), env.param->height(), 1);
  std::fill(env.image.pixels.begin(), env.image.pixels.end(), value);
  return env;
}

class ConstantMapTables : public ::testing::TestWithParam<Case> {};

TEST_P(ConstantMapTables, PdfIsUniformAndEveryRowIsDrawn) {
  const Case& c = GetParam();
  BakeOptions o;
  o.grid = c.grid;
  o.compensated = true;
  const EnvTables t = EnvTables::bake(constant_map(c.grid, c.value), o, c.name);
  for (bool compensated : {false, true})
    for (SamplingMethod m : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical}) {
      const SphericalDistribution* d = t.distribution(m, compensated);
      ASSERT_NE(d, nullptr);
      const std::string what = c.name + " " + method_name(m) + (compensated ? " compensated" : "");
      // The pdf of every texel, hence of every direction.
      double worst = 0.0;
      for (int y = 0; y < d->height(); ++y)
        for (int x = 0; x < d->width(); ++x) worst = std::max(worst, std::abs(d->texel_pdf(x, y) / kUniformPdf - 1.0));
      EXPECT_LT(worst, 1e-5) << what << ": worst relative pdf error over the texels";
      // Samples: their pdf, and a sample in every row (the polar rows of a lat-long are the smallest).
      std::mt19937_64 rng(7);
      std::uniform_real_distribution<double> uni(0.0, 1.0);
      const std::size_t n = 200000;
      std::vector<Vec2> u(n);
      for (Vec2& v : u) v = Vec2(uni(rng), uni(rng));
      std::vector<DirectionSample> s(n);
      d->sample(u, s);
      std::vector<std::size_t> per_row(std::size_t(d->height()), 0);
      double worst_sample = 0.0;
      for (const DirectionSample& ds : s) {
        ++per_row[std::size_t(ds.y)];
        worst_sample = std::max(worst_sample, std::abs(ds.pdf / kUniformPdf - 1.0));
      }
      EXPECT_LT(worst_sample, 1e-5) << what << ": worst relative pdf error of the samples";
      for (int y = 0; y < d->height(); ++y) {
        double omega = 0.0;
        for (int x = 0; x < d->width(); ++x) omega += d->texel_solid_angle(x, y);
        const double expected = double(n) * omega * kUniformPdf;
        // Poisson counts: 6 standard deviations (plus one) around the expected count of the row.
        EXPECT_NEAR(double(per_row[std::size_t(y)]), expected, 6.0 * std::sqrt(expected) + 1.0)
            << what << ": samples in row " << y;
      }
    }
}

INSTANTIATE_TEST_SUITE_P(EveryScale, ConstantMapTables, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& i) { return i.param.name; });

TEST(MakeTable, SubnormalImportanceGivesTheUniformPdf) {
  const int w = 64, h = 32;
  const std::vector<float> importance(std::size_t(w) * h, 1e-42f);
  for (SamplingMethod m : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical}) {
    const auto d = make_table(Kind::LatLong, w, h, importance, m);
    for (int y : {0, 1, h / 2, h - 1})
      EXPECT_NEAR(d->texel_pdf(0, y) / kUniformPdf, 1.0, 1e-5) << method_name(m) << " row " << y;
  }
}

}  // namespace
