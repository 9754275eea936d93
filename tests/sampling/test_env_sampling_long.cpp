// A float-precision stress on the sphere: a 16384 x 8192 lat-long with a 1e6 sun over a 1e-3 sky
// (dynamic range 1e9), baked through EnvTables, sampled by every method, chi-square on the sphere. About 5 GB
// and a minute: ctest label "long" (ENVKIT_LONG_TESTS=1 scripts/test.sh).
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <random>

#include "chi2.h"

using namespace envkit;

namespace {

constexpr int kW = 16384, kH = 8192;
constexpr int kSunX = 9001, kSunY = 2999;

const EnvTables& stress_tables() {
  static const EnvTables tables = [] {
    EnvMap env;
    env.param = std::make_unique<LatLongMap>(kW, kH);
    env.image = Image(kW, kH, 1);
    std::fill(env.image.pixels.begin(), env.image.pixels.end(), 1e-3f);
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 3; ++dx) env.image.at(kSunX + dx, kSunY + dy, 0) = 1e6f;
    return EnvTables::bake(env, BakeOptions{});
  }();
  return tables;
}

}  // namespace

class EnvSamplingLong : public ::testing::TestWithParam<SamplingMethod> {};

// Cells: a coarse 128 x 64 lat-long grid, plus the six sun texels and their ring of neighbours as cells of their
// own (where float tables fail first). Expected counts from the tables' texel probabilities.
TEST_P(EnvSamplingLong, ChiSquareWithA1e9Sun) {
  const EnvTables& t = stress_tables();
  const SphericalDistribution& d = *t.distribution(GetParam());
  const LatLongMap grid(kW, kH);
  constexpr int kCX = 128, kCY = 64, kBlock = kW / kCX;
  const int ring_x0 = kSunX - 1, ring_y0 = kSunY - 1, ring_w = 5, ring_h = 4;
  const auto in_ring = [&](int x, int y) {
    return x >= ring_x0 && x < ring_x0 + ring_w && y >= ring_y0 && y < ring_y0 + ring_h;
  };
  const std::size_t coarse = std::size_t(kCX) * kCY, cells = coarse + std::size_t(ring_w) * ring_h;
  const auto cell_of = [&](int x, int y) {
    if (in_ring(x, y)) return coarse + std::size_t(y - ring_y0) * ring_w + std::size_t(x - ring_x0);
    return std::size_t(y / kBlock) * kCX + std::size_t(x / kBlock);
  };
  // pdf is constant per texel; expected mass per texel = pdf(centre) x Omega(texel).
  std::vector<double> expected(cells, 0.0);
  const std::size_t samples = 2000000;
  // Texel probability = pdf_omega x Omega = pdf_uv / (W H).
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double pdf_uv = d.distribution().pdf(Vec2((x + 0.5) / kW, (y + 0.5) / kH));
      expected[cell_of(x, y)] += double(samples) * pdf_uv / (double(kW) * kH);
    }
  std::vector<double> observed(cells, 0.0);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (std::size_t n = 0; n < samples; ++n) {
    const DirectionSample s = d.sample(Vec2(U(rng), U(rng)));
    ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0);
    const Vec2 p = grid.to_image(s.direction);
    observed[cell_of(std::min(int(p.x), kW - 1), std::min(int(p.y), kH - 1))] += 1.0;
  }
  const chi2::Result r = chi2::test(observed, expected, chi2::sidak_alpha(0.01, 3));
  EXPECT_TRUE(r.passed) << method_name(GetParam()) << ": " << r.message;
  // The sky, 1e-9 of the sun per texel, still holds ~0.5 of the power: it must be sampled about that often.
  double sky_observed = 0.0, sky_expected = 0.0;
  for (std::size_t c = 0; c < coarse; ++c) sky_observed += observed[c], sky_expected += expected[c];
  EXPECT_NEAR(sky_observed / sky_expected, 1.0, 0.01);
}

INSTANTIATE_TEST_SUITE_P(Methods, EnvSamplingLong,
                         ::testing::Values(SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical),
                         [](const ::testing::TestParamInfo<SamplingMethod>& param_info) {
                           return std::string(method_name(param_info.param));
                         });
