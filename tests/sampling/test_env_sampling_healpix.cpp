// Sampling tables baked natively on the HEALPix image grid (env_sampling.h, env_tables.h, healpix.h): the texels
// are uniform in solid angle inside (checked geometrically), sampling matches the pdf on cells independent of the
// HEALPix geometry, the pdf is positive exactly where texels have power, native and resampled bakes, and the
// sizes that are not HEALPix images are refused. The shared catalogue in test_env_sampling.cpp also runs its
// chi-square, pdf, inversion and file round-trip tests on HEALPix maps.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "chi2.h"

using namespace envkit;

namespace {

/// A sun over a dim sky, rasterized flux-exactly onto a HEALPix image of N_side `nside`.
EnvMap healpix_sun_map(int nside, double sun_radiance = 50.0) {
  const probes::SunProbe sun(Vec3(0.3, 0.6, 0.5), 0.15, Vec3(sun_radiance, sun_radiance, sun_radiance),
                             Vec3(1.0, 1.0, 1.0));
  LoadOptions lo;
  lo.kind = Kind::HEALPix;
  lo.convention = &envkit::convention("envkit");
  return make_envmap(probes::rasterize(sun, HealpixMap(nside)), "hp.exr", lo);
}

EnvTables bake_healpix(const EnvMap& map) {
  BakeOptions o;
  o.grid = Kind::HEALPix;
  return EnvTables::bake(map, o, "hp.exr");
}

std::string error_of(const auto& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

const SamplingMethod kMethods[] = {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical};

}  // namespace

// The key fact HEALPix sampling in SphericalDistribution rests on: inside a texel, the direction is an
// area-preserving function of the image position, so a uniform position is uniform in solid angle. Checked with
// the area element |dd/dX x dd/dY| of to_direction (central differences), not with HealpixMap::solid_angle.
TEST(HealpixSampling, TexelsAreUniformInSolidAngleInside) {
  for (int nside : {1, 3, 8}) {
    const HealpixMap map(nside);
    const double h = 1e-5, omega = map.pixel_solid_angle();
    double worst = 0.0;
    for (int j = 0; j < map.height(); ++j)
      for (int i = 0; i < map.width(); ++i)
        for (int b = 0; b < 4; ++b)
          for (int a = 0; a < 4; ++a) {
            const double X = i + (a + 0.5) / 4.0, Y = j + (b + 0.5) / 4.0;
            Vec3 xm, xp, ym, yp;
            ASSERT_TRUE(map.to_direction(Vec2(X - h, Y), xm) && map.to_direction(Vec2(X + h, Y), xp) &&
                        map.to_direction(Vec2(X, Y - h), ym) && map.to_direction(Vec2(X, Y + h), yp));
            const double area = ((xp - xm) % (yp - ym)).length() / (4.0 * h * h);
            worst = std::max(worst, std::abs(area / omega - 1.0));
          }
    EXPECT_LT(worst, 1e-4) << "N_side " << nside;
  }
}

// Chi-square on lat-long cells, which know nothing of the HEALPix layout: expected counts integrate pdf(direction)
// over each cell by a fine midpoint rule, observed counts bin the sampled directions by longitude and latitude.
TEST(HealpixSampling, ChiSquareOnIndependentLatLongCells) {
  const EnvTables t = bake_healpix(healpix_sun_map(4));
  const LatLongMap cells(32, 16);
  constexpr int kSub = 32;  // quadrature points per cell side
  const LatLongMap fine(32 * kSub, 16 * kSub);
  constexpr std::size_t kSamples = 100000;
  const double alpha = chi2::sidak_alpha(0.01, 3);
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    std::vector<double> expected(32 * 16, 0.0), observed(expected.size(), 0.0);
    for (int y = 0; y < fine.height(); ++y) {
      const double omega = fine.solid_angle(0.0, y, 1.0, y + 1.0);
      for (int x = 0; x < fine.width(); ++x) {
        Vec3 dir;
        fine.to_direction(Vec2(x + 0.5, y + 0.5), dir);
        expected[std::size_t(y / kSub) * 32 + std::size_t(x / kSub)] += double(kSamples) * d.pdf(dir) * omega;
      }
    }
    std::mt19937_64 rng(1234 + int(method));
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (std::size_t n = 0; n < kSamples; ++n) {
      const DirectionSample s = d.sample(Vec2(U(rng), U(rng)));
      const Vec2 p = cells.to_image(s.direction);
      const int cx = std::clamp(int(p.x), 0, 31), cy = std::clamp(int(p.y), 0, 15);
      observed[std::size_t(cy) * 32 + std::size_t(cx)] += 1.0;
    }
    const chi2::Result r = chi2::test(observed, expected, alpha);
    EXPECT_TRUE(r.passed) << method_name(method) << ": " << r.message;
  }
}

// pdf > 0 exactly on texels with importance; every sample lands inside the texel it reports, which holds data
// (the 4x3 layout has no blank texels: every texel is one HEALPix pixel) and has power.
TEST(HealpixSampling, PdfIsPositiveExactlyWhereTexelsHavePower) {
  const int nside = 4;
  const HealpixMap map(nside);
  Image image(map.width(), map.height(), 1);
  for (int j = 0; j < map.height(); ++j)
    for (int i = 0; i < map.width(); ++i) image.at(i, j)[0] = ((i * 5 + j * 3) % 4 == 0) ? 0.0f : float(1 + i % 3);
  EnvMap env;
  env.image = image;
  env.param = std::make_unique<HealpixMap>(nside);
  const EnvTables t = bake_healpix(env);
  ASSERT_EQ(t.width(), map.width());
  ASSERT_EQ(t.height(), map.height());
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    for (int j = 0; j < map.height(); ++j)
      for (int i = 0; i < map.width(); ++i) {
        const bool lit = image.at(i, j)[0] > 0.0f;
        Vec3 centre;
        ASSERT_TRUE(map.to_direction(Vec2(i + 0.5, j + 0.5), centre));
        const double p = d.pdf(centre);
        EXPECT_EQ(p > 0.0, lit) << method_name(method) << " texel " << i << "," << j;
        EXPECT_EQ(p, d.texel_pdf(i, j));
        EXPECT_DOUBLE_EQ(d.texel_solid_angle(i, j), map.pixel_solid_angle());
      }
    std::mt19937_64 rng(99 + int(method));
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int n = 0; n < 20000; ++n) {
      const DirectionSample s = d.sample(Vec2(U(rng), U(rng)));
      ASSERT_GT(image.at(s.x, s.y)[0], 0.0f) << method_name(method);
      const Vec2 p = map.to_image(s.direction);
      ASSERT_EQ(int(p.x), s.x);
      ASSERT_EQ(int(p.y), s.y);
      ASSERT_GT(s.pdf, 0.0);
    }
    // u.x = 0 puts the offset on the texel's edge, where to_image may name the neighbouring texel: the sampler keeps
    // offsets to_image_tolerance() inside, so the sample is located in its own texel.
    for (int n = 0; n < 500; ++n) {
      const DirectionSample s = d.sample(Vec2(0.0, (n + 0.5) / 500.0));
      int x = -1, y = -1;
      d.texel_of(s.direction, x, y);
      ASSERT_EQ(x, s.x) << method_name(method) << " n " << n;
      ASSERT_EQ(y, s.y) << method_name(method) << " n " << n;
      ASSERT_EQ(d.pdf(s.direction), s.pdf);
    }
  }
}

// A HEALPix map is baked on its own texels (no resampling), its importance is its luminance texel for texel; a
// lat-long map is resampled onto a HEALPix grid of about as many texels, conserving power.
TEST(HealpixSampling, BakesHealpixMapsNativelyAndResamplesOthers) {
  const EnvMap hp = healpix_sun_map(8);
  const EnvTables t = bake_healpix(hp);
  EXPECT_EQ(t.grid(), Kind::HEALPix);
  EXPECT_EQ(t.width(), 32);
  EXPECT_EQ(t.height(), 24);
  EXPECT_EQ(t.descriptor().find("resampled_from"), std::string::npos);
  double power = 0.0;
  for (std::size_t k = 0; k < hp.image.texel_count(); ++k) {
    EXPECT_NEAR(t.importance()[k], hp.image.pixels[3 * k], 1e-5 * hp.image.pixels[3 * k]);
    power += double(hp.image.pixels[3 * k]) * HealpixMap(8).pixel_solid_angle();
  }
  EXPECT_NEAR(t.total_importance() / power, 1.0, 1e-6);

  const probes::SunProbe sun(Vec3(0.3, 0.6, 0.5), 0.15, Vec3(50, 50, 50), Vec3(1, 1, 1));
  LoadOptions lo;
  lo.kind = Kind::LatLong;
  lo.convention = &envkit::convention("envkit");
  const EnvMap ll = make_envmap(probes::rasterize(sun, LatLongMap(64, 32)), "ll.exr", lo);
  const EnvTables r = bake_healpix(ll);
  EXPECT_EQ(r.width(), 4 * 13);  // N_side = round(sqrt(64 x 32 / 12))
  EXPECT_EQ(r.height(), 3 * 13);
  EXPECT_NE(r.descriptor().find("resampled_from"), std::string::npos);
  EXPECT_NEAR(r.total_importance() / sun.total_power().x, 1.0, 1e-3);
  const SphericalDistribution& d = *r.distribution(SamplingMethod::Hierarchical);
  EXPECT_GT(d.pdf(sun.direction()), 10.0 * d.pdf(-sun.direction()));

  // --resolution: a coarser HEALPix importance map, the radiance grid stays the bake grid.
  BakeOptions o;
  o.grid = Kind::HEALPix;
  o.importance_width = 16;
  o.importance_height = 12;
  const EnvTables low = EnvTables::bake(hp, o, "hp.exr");
  EXPECT_EQ(low.width(), 16);
  EXPECT_EQ(low.grid_width(), 32);
  EXPECT_NEAR(low.total_importance() / power, 1.0, 1e-4);
}

TEST(HealpixSampling, SizesThatAreNotHealpixImagesAreRefused) {
  const std::vector<float> weights(100, 1.0f);
  const auto uniform = std::make_shared<CdfDistribution2D>(weights.data(), 10, 10);
  EXPECT_NE(error_of([&] { SphericalDistribution(Kind::HEALPix, uniform); }).find("4 N_side x 3 N_side"),
            std::string::npos);

  const EnvMap hp = healpix_sun_map(4);
  BakeOptions o;
  o.grid = Kind::HEALPix;
  o.width = o.height = 16;
  EXPECT_NE(error_of([&] { EnvTables::bake(hp, o); }).find("a HEALPix grid must be 4 N_side x 3 N_side, got 16x16"),
            std::string::npos);
  o.width = o.height = 0;
  o.importance_width = 8;
  o.importance_height = 8;
  EXPECT_NE(error_of([&] { EnvTables::bake(hp, o); }).find("importance resolution 8x8"), std::string::npos);

  // A table file whose descriptor claims a HEALPix size no HEALPix image has: refused with the file's name.
  const EnvTables t = bake_healpix(hp);
  const std::string path = (std::filesystem::temp_directory_path() / "envkit_bad_healpix.envtbl").string();
  t.save(path);
  std::vector<std::byte> bytes;
  {
    std::ifstream f(path, std::ios::binary);
    for (char c; f.get(c);) bytes.push_back(std::byte(c));
  }
  const std::string from = "\"width\": 16", to = "\"width\": 15";
  bool patched = false;
  for (const TableFileSection& s : table_file_sections(bytes)) {
    if (s.name != "descriptor") continue;
    std::string text(reinterpret_cast<const char*>(bytes.data() + s.offset), s.size);
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << text;
    for (std::size_t k = 0; k < to.size(); ++k) bytes[s.offset + at + k] = std::byte(to[k]);
    patched = true;
  }
  ASSERT_TRUE(patched);
  reseal_table_file(bytes);
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  const std::string err = error_of([&] { EnvTables::load(path); });
  std::filesystem::remove(path);
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_NE(err.find("corrupt descriptor (grid or size)"), std::string::npos) << err;
}
