// The environment light's combined look-up (radiance and density in one texel search, what MIS's BSDF samples
// use) gives exactly what radiance() and pdf() give separately, for every distribution, rotated environments,
// octahedral and HEALPix grids and importance coarser than the radiance grid.
#include <envkit/core/error.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/env_light.h>
#include <envkit/sampling/lobe_product.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

using namespace envkit;
using namespace envkit::render;

namespace {

Vec3 random_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (;;) {
    const Vec3 d(u(rng), u(rng), u(rng));
    const double n = d.length();
    if (n > 1e-3 && n <= 1.0) return d / n;
  }
}

void expect_lookup_matches(const EnvMap& map, const BakeOptions& bake, const Mat3& rotation, const char* what) {
  const auto tables = std::make_shared<EnvTables>(EnvTables::bake(map, bake));
  const EnvironmentLight light(map, tables, rotation, 1.5);
  std::mt19937_64 rng(11);
  int checked = 0;
  for (const SamplingMethod m : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical})
    for (const bool compensated : {false, true}) {
      const SphericalDistribution& dist = light.distribution(m, compensated);
      for (int k = 0; k < 4000; ++k) {
        // Random directions, the poles and the seam exactly, and directions the distribution draws.
        Vec3 d = k == 0 ? Vec3(0, 1, 0) : k == 1 ? Vec3(0, -1, 0) : k == 2 ? Vec3(0, 0, -1) : random_direction(rng);
        const bool drawn = k % 2 == 1 && k > 2;
        const LightSample s = light.sample(dist, Vec2(std::fmod(k * 0.618034, 1.0), (k % 97) / 97.0));
        if (drawn) d = s.direction;
        const LightSample l = light.lookup(dist, d);
        const Vec3 L = light.radiance(d);
        for (const Vec3& R : {light.radiance(l), light.radiance(light.lookup(d))}) {
          ASSERT_EQ(R.x, L.x) << what << " k " << k;
          ASSERT_EQ(R.y, L.y) << what << " k " << k;
          ASSERT_EQ(R.z, L.z) << what << " k " << k;
        }
        ASSERT_EQ(l.pdf, light.pdf(dist, d)) << what << " k " << k;
        // A drawn direction is looked up in the texel it was drawn from, with the density it was drawn with; except
        // where u.y = 0 draws a texel's edge, which its neighbour shares (a lat-long pole is an edge of a whole row).
        if (drawn && k % 97 != 0) {
          ASSERT_EQ(l.texel, s.texel) << what << " k " << k;
          ASSERT_EQ(l.pdf, s.pdf) << what << " k " << k;
        }
        ++checked;
      }
    }
  EXPECT_EQ(checked, 6 * 4000);
}

/// The default probe on a 128 x 64 lat-long grid.
EnvMap default_probe_latlong() {
  LatLongMap grid(128, 64);
  LoadOptions load;
  load.kind = Kind::LatLong;
  return make_envmap(probes::rasterize(*probes::make_default_probe(), grid), "default", load);
}

/// The light of `map` with its tables and their compensated twins, rotated by yaw 35 and pitch 10 degrees.
std::unique_ptr<EnvironmentLight> rotated_light(const EnvMap& map) {
  BakeOptions bake;
  bake.compensated = true;
  return std::make_unique<EnvironmentLight>(map, std::make_shared<EnvTables>(EnvTables::bake(map, bake)),
                                            rotation_from_euler_degrees(35.0, 10.0, 0.0), 1.0);
}

}  // namespace

TEST(EnvironmentLight, LookupIsRadianceAndPdfTogether) {
  const EnvMap map = default_probe_latlong();
  BakeOptions bake;
  bake.compensated = true;
  expect_lookup_matches(map, bake, identity3(), "lat-long");
  expect_lookup_matches(map, bake, rotation_from_euler_degrees(70.0, 20.0, -5.0), "lat-long, rotated");
  BakeOptions coarse;
  coarse.compensated = true;
  coarse.importance_width = 32;
  coarse.importance_height = 16;
  expect_lookup_matches(map, coarse, identity3(), "lat-long, coarser importance");
  BakeOptions octahedral = bake;
  octahedral.grid = Kind::Octahedral;
  expect_lookup_matches(map, octahedral, rotation_from_euler_degrees(-30.0, 0.0, 10.0), "octahedral");
  BakeOptions healpix = bake;
  healpix.grid = Kind::HEALPix;
  expect_lookup_matches(map, healpix, rotation_from_euler_degrees(40.0, -10.0, 5.0), "healpix");
  healpix.width = 64;
  healpix.height = 48;
  healpix.importance_width = 16;
  healpix.importance_height = 12;
  expect_lookup_matches(map, healpix, identity3(), "healpix, coarser importance");
}

// Tables baked on a HEALPix map's own texels: the light looks radiance up in the map's texels (no resampling), and
// a light sample carries the radiance of the texel its direction lies in, also for offsets on a texel's edge
// (u = 0 picks offset 0), where HEALPix's to_image could name the neighbouring base pixel.
TEST(EnvironmentLight, NativeHealpixTablesUseTheMapsTexels) {
  const HealpixMap grid(16);
  LoadOptions load;
  load.kind = Kind::HEALPix;
  const EnvMap map = make_envmap(probes::rasterize(*probes::make_default_probe(), grid), "default", load);
  BakeOptions bake;
  bake.grid = Kind::HEALPix;
  const auto tables = std::make_shared<EnvTables>(EnvTables::bake(map, bake));
  ASSERT_EQ(tables->width(), grid.width());
  const EnvironmentLight light(map, tables, identity3(), 1.0);
  for (const SamplingMethod m : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical}) {
    const SphericalDistribution& dist = light.distribution(m, false);
    for (int k = 0; k < 2000; ++k) {
      const Vec2 u = k < 89 ? Vec2(0.0, (k + 0.5) / 89.0) : Vec2(std::fmod(k * 0.618034, 1.0), (k % 89 + 0.5) / 89.0);
      const LightSample s = light.sample(dist, u);
      const Vec2 p = grid.to_image(s.direction);
      const float* texel = map.image.at(int(p.x), int(p.y));
      ASSERT_FLOAT_EQ(float(light.radiance(s).x), texel[0]) << method_name(m) << " k " << k;
      ASSERT_FLOAT_EQ(float(light.radiance(s).z), texel[2]) << method_name(m) << " k " << k;
      ASSERT_EQ(s.pdf, light.pdf(dist, s.direction)) << method_name(m) << " k " << k;
    }
  }
}

// A mixture of two tables over one grid (a plastic's base and coat): each sample carries the mixture's density,
// which lookup() and pdf() give too; shares 0 and 1 are the tables alone; L / pdf integrates to the map's flux;
// tables over different grids are refused.
TEST(EnvironmentLight, AMixtureDrawsFromBothTablesWithTheMixturesDensity) {
  const EnvMap map = default_probe_latlong();
  const std::unique_ptr<EnvironmentLight> rotated = rotated_light(map);
  const EnvironmentLight& light = *rotated;
  // The compensated table is 0 on every texel below the mean: the plain one covers them.
  const SphericalDistribution& plain = light.distribution(SamplingMethod::Hierarchical, false);
  const SphericalDistribution& compensated = light.distribution(SamplingMethod::Hierarchical, true);
  for (const double share : {0.0, 0.3, 1.0}) {
    const LightTable mixture(plain, compensated, share);
    const int n = 1 << 16;
    double flux = 0.0;
    for (int k = 0; k < n; ++k) {
      // A stratified set: k / n in x, a golden-ratio sequence in y.
      const Vec2 u((k + 0.5) / n, std::fmod(0.5 + k * 0.6180339887498949, 1.0));
      const LightSample s = light.sample(mixture, u);
      ASSERT_GT(s.pdf, 0.0) << share << " k " << k;
      const double expected =
          (1.0 - share) * light.pdf(plain, s.direction) + share * light.pdf(compensated, s.direction);
      ASSERT_NEAR(s.pdf, expected, 1e-12 * expected) << share << " k " << k;
      ASSERT_NEAR(light.lookup(mixture, s.direction).pdf, s.pdf, 1e-12 * s.pdf) << share << " k " << k;
      ASSERT_EQ(light.pdf(mixture, s.direction), light.lookup(mixture, s.direction).pdf) << share << " k " << k;
      if (share == 0.0) {
        ASSERT_EQ(s.direction.x, light.sample(plain, u).direction.x) << " k " << k;
      }
      if (share == 1.0) {
        ASSERT_EQ(s.direction.x, light.sample(compensated, u).direction.x) << " k " << k;
      }
      flux += light.radiance(s).y / s.pdf;
    }
    // The compensated table alone misses the texels below the mean: only a mixture with the plain one sees all.
    const double expected_flux = 4.0 * kPi * light.mean_radiance().y;
    if (share < 1.0) {
      EXPECT_NEAR(flux / n, expected_flux, 2e-3 * expected_flux) << "share " << share;
    } else {
      EXPECT_LT(flux / n, 0.99 * expected_flux);
    }
  }
  BakeOptions coarse;
  coarse.compensated = true;
  coarse.importance_width = 32;
  coarse.importance_height = 16;
  const auto coarse_tables = std::make_shared<EnvTables>(EnvTables::bake(map, coarse));
  const EnvironmentLight coarse_light(map, coarse_tables, identity3(), 1.0);
  const LightTable mixed_grids(plain, coarse_light.distribution(SamplingMethod::Hierarchical, false), 0.5);
  EXPECT_THROW(light.sample(mixed_grids, Vec2(0.5, 0.5)), Error);
  EXPECT_THROW(light.lookup(mixed_grids, Vec3(0, 1, 0)), Error);
}

// A shading point's light samples drawn together are the samples drawn one by one, bit for bit (direction, density,
// radiance texel): for product tables' mixtures (their descents interleaved), a single table, the baked tables, a
// rotated light and groups of any size; spans of different sizes are refused.
TEST(EnvironmentLight, SamplesDrawnTogetherAreTheSamplesDrawnOneByOne) {
  const EnvMap map = default_probe_latlong();
  const std::unique_ptr<EnvironmentLight> rotated = rotated_light(map);
  const EnvironmentLight& light = *rotated;
  const SphericalDistribution& plain = light.distribution(SamplingMethod::Hierarchical, false);
  const LobeProductTables product(plain, {{Lobe::Shape::Cosine, 1.0}, {Lobe::Shape::Ggx, 0.05}});
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int point = 0; point < 40; ++point) {
    const Vec3 axis = random_direction(rng);
    const SphericalDistribution& wide = product.table(0, axis).distribution;
    const SphericalDistribution& narrow = product.table(1, axis).distribution;
    const LightTable cases[] = {LightTable(wide, narrow, U(rng)),
                                LightTable(narrow),
                                LightTable(wide, narrow, 1.0),
                                LightTable(plain),
                                LightTable(light.distribution(SamplingMethod::Cdf, false)),
                                LightTable(plain, light.distribution(SamplingMethod::Hierarchical, true), 0.4)};
    for (const LightTable& table : cases) {
      const std::size_t n = std::size_t(1 + point % 9) * (point == 39 ? 20 : 1);
      std::vector<Vec2> u(n);
      for (Vec2& v : u) v = Vec2(U(rng), U(rng));
      std::vector<LightSample> together(n);
      light.sample(table, u, together);
      for (std::size_t k = 0; k < n; ++k) {
        const LightSample one = light.sample(table, u[k]);
        ASSERT_EQ(together[k].direction.x, one.direction.x) << point << " " << k;
        ASSERT_EQ(together[k].direction.y, one.direction.y) << point << " " << k;
        ASSERT_EQ(together[k].direction.z, one.direction.z) << point << " " << k;
        ASSERT_EQ(together[k].pdf, one.pdf) << point << " " << k;
        ASSERT_EQ(together[k].texel, one.texel) << point << " " << k;
      }
    }
  }
  std::vector<Vec2> u(3, Vec2(0.5, 0.5));
  std::vector<LightSample> out(2);
  EXPECT_THROW(light.sample(LightTable(plain), u, out), Error);
}
