// Analytic probes: closed-form integrals, flux-exact rasterization into lat-long, cube and other maps,
// the default outdoor probe, and the envprobe command line.
#include <envkit/core/error.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/probes.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#if __has_include(<envkit/io/image_io.h>)
#include <envkit/io/image_io.h>
#endif

namespace envkit::probes {
namespace {

// Largest per-channel relative error; a channel whose expected value is 0 is measured against the largest
// channel instead.
double relative_error(const Vec3& got, const Vec3& want) {
  const double largest = std::max({std::abs(want.x), std::abs(want.y), std::abs(want.z), 1e-300});
  double e = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double scale = want[c] != 0.0 ? std::abs(want[c]) : largest;
    e = std::max(e, std::abs(got[c] - want[c]) / scale);
  }
  return e;
}

// Independent numerical integral of f over the sphere (midpoint rule in (cos theta, phi), fine grid).
Vec3 integrate_sphere(const std::function<Vec3(const Vec3&)>& f, int n = 600) {
  Vec3 sum(0.0);
  for (int a = 0; a < n; ++a) {
    const double z = -1.0 + 2.0 * (a + 0.5) / n, s = std::sqrt(1.0 - z * z);
    for (int b = 0; b < 2 * n; ++b) {
      const double phi = kPi * (b + 0.5) / n;
      sum += f(Vec3(s * std::cos(phi), z, s * std::sin(phi)));
    }
  }
  return sum * (kFourPi / (2.0 * n * n));
}

struct NamedProbe {
  std::string name;
  std::shared_ptr<Probe> probe;
  bool exact_everywhere;  // flux exact (1e-6) in any map, not only in lat-long
};

std::vector<NamedProbe> analytic_probes() {
  const Vec3 sun_dir = direction_from_elevation_azimuth(radians(35.0), radians(45.0));
  return {
      {"constant", std::make_shared<ConstantProbe>(Vec3(0.25, 1.5, 3.0)), true},
      {"gradient_quadratic",
       std::make_shared<GradientProbe>(Vec3(0.2, 0.3, 0.5), Vec3(1.0, 0.7, 0.2), GradientProbe::Form::Quadratic),
       false},
      {"gradient_upper",
       std::make_shared<GradientProbe>(Vec3(0.1, 0.2, 0.4), Vec3(2.0, 1.0, 0.5), GradientProbe::Form::UpperLinear),
       false},
      {"sun", std::make_shared<SunProbe>(sun_dir, radians(0.265), Vec3(3e4, 2.8e4, 2.5e4), Vec3(0.05, 0.08, 0.12)),
       true},
      {"big_sun", std::make_shared<SunProbe>(Vec3(1, -2, 3), radians(12.0), Vec3(50, 40, 30), Vec3(0.1)), true},
      {"checker", std::make_shared<CheckerProbe>(4, 8, Vec3(1.0, 0.5, 0.25), Vec3(0.1, 0.2, 0.4)), false},
      {"checker_odd", std::make_shared<CheckerProbe>(3, 5, Vec3(2.0, 0.0, 1.0), Vec3(0.0, 1.0, 0.5)), false},
  };
}

// --- closed forms ---------------------------------------------------------------------------------------------

TEST(ProbeClosedForm, PowersMatchTheFormulas) {
  EXPECT_LT(relative_error(ConstantProbe(Vec3(1, 2, 3)).total_power(), Vec3(1, 2, 3) * kFourPi), 1e-15);
  const Vec3 a(0.2, 0.3, 0.5), b(1.0, 0.7, 0.2);
  EXPECT_LT(relative_error(GradientProbe(a, b, GradientProbe::Form::Quadratic).total_power(),
                           a * kFourPi + b * (kFourPi / 3.0)),
            1e-15);
  EXPECT_LT(relative_error(GradientProbe(a, b, GradientProbe::Form::UpperLinear).total_power(), a * kFourPi + b * kPi),
            1e-15);
  const double alpha = radians(0.265);
  const Vec3 ls(3e4), lsky(0.1);
  const double omega = kTwoPi * (1.0 - std::cos(alpha));
  EXPECT_LT(
      relative_error(SunProbe(Vec3(0, 1, 0), alpha, ls, lsky).total_power(), ls * omega + lsky * (kFourPi - omega)),
      1e-9);
  // Checker 2 x 2 of colours A, B: each hemisphere holds one cell of each colour.
  const Vec3 ca(1, 0, 0), cb(0, 1, 0);
  EXPECT_LT(relative_error(CheckerProbe(2, 2, ca, cb).total_power(), Vec3(kTwoPi, kTwoPi, 0.0)), 1e-14);
  // 1 x 3: two cells of A (b = 0, 2), one of B.
  EXPECT_LT(relative_error(CheckerProbe(1, 3, ca, cb).total_power(), Vec3(2.0 * kFourPi / 3.0, kFourPi / 3.0, 0.0)),
            1e-14);
}

TEST(ProbeClosedForm, PowersMatchNumericalIntegration) {
  for (const NamedProbe& p : analytic_probes()) {
    if (p.name == "sun") continue;  // far too small for a fixed grid; covered by the rasterization tests
    const Vec3 numeric = integrate_sphere([&](const Vec3& d) { return p.probe->radiance(d); });
    EXPECT_LT(relative_error(numeric, p.probe->total_power()), 2e-3) << p.name;
  }
}

TEST(ProbeClosedForm, UpwardIrradianceMatchesNumericalIntegration) {
  for (const NamedProbe& p : analytic_probes()) {
    const std::optional<Vec3> e = p.probe->upward_irradiance();
    if (p.name == "sun") {
      ASSERT_TRUE(e.has_value());
      continue;
    }
    if (!e) continue;
    const Vec3 numeric = integrate_sphere([&](const Vec3& d) { return p.probe->radiance(d) * std::max(d.y, 0.0); });
    EXPECT_LT(relative_error(numeric, *e), 2e-3) << p.name;
  }
  // The sun's disk term: irradiance grows by (Ls - Lsky) pi sin^2(alpha) sin(elevation).
  const double alpha = radians(5.0), elevation = radians(40.0);
  const SunProbe sun(direction_from_elevation_azimuth(elevation, 0.3), alpha, Vec3(100.0), Vec3(1.0));
  const Vec3 numeric = integrate_sphere([&](const Vec3& d) { return sun.radiance(d) * std::max(d.y, 0.0); }, 1000);
  EXPECT_LT(relative_error(numeric, *sun.upward_irradiance()), 2e-3);
  // A disk straddling the horizon has no closed form here.
  EXPECT_FALSE(SunProbe(Vec3(1, 0, 0), alpha, Vec3(1), Vec3(0)).upward_irradiance().has_value());
}

TEST(ProbeClosedForm, ExactLatLongRectanglesAddUp) {
  // Integrals over a random partition of the domain sum to the total power.
  for (const NamedProbe& p : analytic_probes()) {
    Vec3 sum(0.0), part;
    const double us[] = {0.0, 0.13, 0.5, 0.77, 1.0}, vs[] = {0.0, 0.21, 0.5, 0.5001, 0.9, 1.0};
    for (int a = 0; a + 1 < 5; ++a)
      for (int b = 0; b + 1 < 6; ++b) {
        ASSERT_TRUE(p.probe->integrate_latlong(us[a], us[a + 1], vs[b], vs[b + 1], part)) << p.name;
        sum += part;
      }
    // Lat-long integrals cover the background only; add the features' excess.
    for (const Feature& f : p.probe->features()) sum += f.excess * f.solid_angle;
    EXPECT_LT(relative_error(sum, p.probe->total_power()), 1e-13) << p.name;
  }
}

TEST(ProbeClosedForm, BadArgumentsThrow) {
  EXPECT_THROW(ConstantProbe(Vec3(-1, 0, 0)), Error);
  EXPECT_THROW(ConstantProbe(Vec3(std::nan(""), 0, 0)), Error);
  EXPECT_THROW(SunProbe(Vec3(0, 0, 0), 0.01, Vec3(1), Vec3(0)), Error);
  EXPECT_THROW(SunProbe(Vec3(0, 1, 0), 0.0, Vec3(1), Vec3(0)), Error);
  EXPECT_THROW(CheckerProbe(0, 4, Vec3(1), Vec3(0)), Error);
  EXPECT_THROW(GradientProbe(Vec3(0.1), Vec3(-1.0)), Error);
  const LatLongMap map(8, 4);
  EXPECT_THROW(TexelProbe(map, 8, 0, Vec3(1), Vec3(0)), Error);
  EXPECT_THROW(TexelProbe(map, 0, -1, Vec3(1), Vec3(0)), Error);
}

// --- rasterization: flux ------------------------------------------------------------------------------------

struct Size {
  int w, h;
};

TEST(ProbeRaster, LatLongPowerIsExact) {
  const Size sizes[] = {{1, 1}, {2, 1}, {3, 3}, {5, 3}, {7, 5}, {64, 32}, {512, 256}};
  for (const NamedProbe& p : analytic_probes())
    for (const Size& s : sizes)
      for (TexelGrid grid : {TexelGrid::Centre, TexelGrid::Corner}) {
        const LatLongMap map(s.w, s.h, grid);
        const Image img = rasterize(*p.probe, map);
        EXPECT_LT(relative_error(image_power(img, map), p.probe->total_power()), 1e-6)
            << p.name << " " << map.describe();
      }
}

TEST(ProbeRaster, LatLongSampledPathIsAccurate) {
  // Without the closed-form rectangles the supersampler alone must reach 1e-4 (1e-6 for constant and suns).
  RasterOptions opt;
  opt.exact_latlong = false;
  const Size sizes[] = {{1, 1}, {2, 1}, {3, 3}, {7, 5}, {256, 128}};
  for (const NamedProbe& p : analytic_probes())
    for (const Size& s : sizes) {
      const LatLongMap map(s.w, s.h);
      const Image img = rasterize(*p.probe, map, opt);
      EXPECT_LT(relative_error(image_power(img, map), p.probe->total_power()), p.exact_everywhere ? 1e-6 : 1e-4)
          << p.name << " " << map.describe();
    }
}

TEST(ProbeRaster, LargeLatLongPowerIsExact) {
  const LatLongMap map(2048, 1024);
  for (const NamedProbe& p : analytic_probes()) {
    if (p.name != "sun" && p.name != "checker") continue;
    const Image img = rasterize(*p.probe, map);
    EXPECT_LT(relative_error(image_power(img, map), p.probe->total_power()), 1e-6) << p.name;
  }
}

TEST(ProbeRaster, CubePowerWithinTolerance) {
  for (const NamedProbe& p : analytic_probes())
    for (int n : {1, 2, 3, 8, 17, 32})
      for (TexelGrid grid : {TexelGrid::Centre, TexelGrid::Corner}) {
        // Sampled probes (the slow ones) alternate grids between sizes to keep the suite fast.
        if (!p.exact_everywhere && (n % 2 == 0) != (grid == TexelGrid::Centre)) continue;
        const CubeMap map(n, CubeLayout::VerticalStrip, CubeBasis::Envkit, grid);
        const Image img = rasterize(*p.probe, map);
        EXPECT_LT(relative_error(image_power(img, map), p.probe->total_power()), p.exact_everywhere ? 1e-6 : 1e-4)
            << p.name << " " << map.describe();
      }
}

TEST(ProbeRaster, CubeCrossLayoutsLeaveBlankCellsEmpty) {
  const SunProbe sun(Vec3(0.3, 0.2, 1.0), radians(0.5), Vec3(1e4), Vec3(0.2));
  for (CubeLayout layout : {CubeLayout::HorizontalCross, CubeLayout::VerticalCross})
    for (CubeBasis basis : {CubeBasis::Envkit, CubeBasis::GL}) {
      const CubeMap map(16, layout, basis);
      RasterOptions opt;
      opt.alpha = true;
      const Image img = rasterize(sun, map, opt);
      ASSERT_EQ(img.channels, 4);
      EXPECT_LT(relative_error(image_power(img, map), sun.total_power()), 1e-6) << map.describe();
      for (int j = 0; j < img.height; ++j)
        for (int i = 0; i < img.width; ++i) {
          const bool covered = map.face_at(i, j) >= 0;
          EXPECT_EQ(img.at(i, j, 3), covered ? 1.0f : 0.0f);
          if (!covered) {
            EXPECT_EQ(img.at(i, j, 0), 0.0f);
          }
        }
    }
}

TEST(ProbeRaster, SunSmallerThanATexelKeepsItsFlux) {
  const Vec3 dir = direction_from_elevation_azimuth(radians(20.0), radians(-30.0));
  const SunProbe sun(dir, radians(0.05), Vec3(1e6, 5e5, 2e5), Vec3(0.01));
  const LatLongMap map(64, 32);
  RasterStats stats;
  const Image img = rasterize(sun, map, {}, &stats);
  EXPECT_LT(relative_error(image_power(img, map), sun.total_power()), 1e-6);
  ASSERT_EQ(stats.features.size(), 1u);
  EXPECT_FALSE(stats.features[0].missed);
  EXPECT_NEAR(stats.features[0].scale, 1.0, 0.02);  // the supersampling itself found the disk's area
  // The brightest texel is the one that sees the sun's centre.
  int bi = 0, bj = 0;
  for (int j = 0; j < img.height; ++j)
    for (int i = 0; i < img.width; ++i)
      if (img.at(i, j, 0) > img.at(bi, bj, 0)) bi = i, bj = j;
  const Vec2 p = map.to_image(dir);
  EXPECT_EQ(bi, static_cast<int>(p.x));
  EXPECT_EQ(bj, static_cast<int>(p.y));
  // Also into a cube map (sun inside one face texel).
  const CubeMap cube(8);
  EXPECT_LT(relative_error(image_power(rasterize(sun, cube), cube), sun.total_power()), 1e-6);
}

TEST(ProbeRaster, MissedSunGoesToItsCentreTexel) {
  // With no refinement allowed, a 0.001 deg sun falls between the subsamples: its flux must still arrive, in
  // the texel that contains its centre.
  const Vec3 dir = direction_from_elevation_azimuth(radians(10.0), radians(100.0));
  const SunProbe sun(dir, radians(0.001), Vec3(1e6), Vec3(0.0));
  RasterOptions opt;
  opt.max_feature_depth = 0;
  for (int n : {16, 64}) {
    const LatLongMap map(2 * n, n);
    RasterStats stats;
    const Image img = rasterize(sun, map, opt, &stats);
    EXPECT_TRUE(stats.features[0].missed);
    EXPECT_LT(relative_error(image_power(img, map), sun.total_power()), 1e-6);
    const Vec2 p = map.to_image(dir);
    EXPECT_GT(img.at(static_cast<int>(p.x), static_cast<int>(p.y), 0), 0.0f);
  }
}

TEST(ProbeRaster, OtherParameterizationsKeepFlux) {
  const std::vector<NamedProbe> probes = analytic_probes();
  for (Kind kind : {Kind::MirrorBall, Kind::AngularMap, Kind::Octahedral, Kind::DualParaboloid}) {
    ParamSpec spec;
    spec.kind = kind;
    natural_image_size(kind, 48, CubeLayout::VerticalStrip, spec.width, spec.height);
    const std::unique_ptr<Parameterization> map = make_parameterization(spec);
    for (const NamedProbe& p : probes) {
      if (p.name != "constant" && p.name != "sun" && p.name != "gradient_quadratic") continue;
      RasterOptions opt;
      opt.alpha = true;
      const Image img = rasterize(*p.probe, *map, opt);
      // Whatever the map covers (4 pi for these) carries the flux; rims with degenerate texels get 1e-4.
      EXPECT_LT(relative_error(image_power(img, *map), p.probe->total_power()), 1e-4)
          << p.name << " " << map->describe();
      for (int j = 0; j < img.height; ++j)
        for (int i = 0; i < img.width; ++i) {
          const bool covered = map->texel_solid_angle(i, j) > 0.0;
          ASSERT_EQ(img.at(i, j, 3), covered ? 1.0f : 0.0f) << map->describe() << " " << i << "," << j;
          if (!covered) {
            ASSERT_EQ(img.at(i, j, 0), 0.0f);
          }
          for (int c = 0; c < 3; ++c) ASSERT_TRUE(std::isfinite(img.at(i, j, c)) && img.at(i, j, c) >= 0.0f);
        }
    }
  }
}

// --- rasterization: per texel -------------------------------------------------------------------------------

TEST(ProbeRaster, ConstantIsExactInEveryTexel) {
  const Vec3 l(0.1, 1.7, 123.456);
  const ConstantProbe probe(l);
  std::vector<std::unique_ptr<Parameterization>> maps;
  maps.push_back(std::make_unique<LatLongMap>(1, 1));
  maps.push_back(std::make_unique<LatLongMap>(7, 5, TexelGrid::Corner));
  maps.push_back(std::make_unique<LatLongMap>(128, 64));
  maps.push_back(std::make_unique<CubeMap>(5, CubeLayout::HorizontalCross));
  maps.push_back(std::make_unique<CubeMap>(4, CubeLayout::VerticalStrip, CubeBasis::GL, TexelGrid::Corner));
  for (const auto& map : maps) {
    const Image img = rasterize(probe, *map);
    for (int j = 0; j < img.height; ++j)
      for (int i = 0; i < img.width; ++i) {
        if (!(map->texel_solid_angle(i, j) > 0.0)) continue;
        for (int c = 0; c < 3; ++c) ASSERT_EQ(img.at(i, j, c), static_cast<float>(l[c])) << map->describe();
      }
  }
}

TEST(ProbeRaster, CheckerIsExactPerTexelInAlignedLatLong) {
  const Vec3 a(1.0, 0.5, 0.25), b(0.1, 0.2, 0.4);
  const CheckerProbe checker(4, 8, a, b);
  for (bool exact : {true, false}) {
    RasterOptions opt;
    opt.exact_latlong = exact;
    for (const Size& s : {Size{8, 4}, Size{64, 32}, Size{24, 12}}) {
      const LatLongMap map(s.w, s.h);
      const Image img = rasterize(checker, map, opt);
      for (int j = 0; j < s.h; ++j)
        for (int i = 0; i < s.w; ++i) {
          const int cell_a = j * 4 / s.h, cell_b = i * 8 / s.w;
          const Vec3& want = ((cell_a + cell_b) % 2 == 0) ? a : b;
          for (int c = 0; c < 3; ++c)
            ASSERT_EQ(img.at(i, j, c), static_cast<float>(want[c])) << i << "," << j << " exact=" << exact;
        }
      EXPECT_LT(relative_error(image_power(img, map), checker.total_power()), 1e-6);
    }
  }
}

TEST(ProbeRaster, CheckerTexelAveragesInUnalignedLatLong) {
  // A 2 x 2 checker in a 3 x 3 lat-long: the centre texel spans all four cells in equal parts by azimuth;
  // check one texel against its hand-computed average.
  const CheckerProbe checker(2, 2, Vec3(1, 0, 0), Vec3(0, 1, 0));
  const LatLongMap map(3, 3);
  const Image img = rasterize(checker, map);
  // Texel (0, 0): u in [0, 1/3] (cell b = 0), theta in [0, 60 deg] (cell a = 0): pure colour A.
  EXPECT_EQ(img.at(0, 0, 0), 1.0f);
  EXPECT_EQ(img.at(0, 0, 1), 0.0f);
  // Texel (1, 1): u in [1/3, 2/3] half in b = 0 and half in b = 1; theta symmetric about the equator: 50/50.
  EXPECT_NEAR(img.at(1, 1, 0), 0.5f, 1e-6);
  EXPECT_NEAR(img.at(1, 1, 1), 0.5f, 1e-6);
}

TEST(ProbeRaster, TexelProbeIntoItsOwnMapIsExact) {
  const Vec3 v(500.0, 250.0, 100.0), floor(0.1, 0.2, 0.3);
  std::vector<std::unique_ptr<Parameterization>> maps;
  maps.push_back(std::make_unique<LatLongMap>(1, 1));
  maps.push_back(std::make_unique<LatLongMap>(2, 1));
  maps.push_back(std::make_unique<LatLongMap>(9, 5));
  maps.push_back(std::make_unique<LatLongMap>(64, 32, TexelGrid::Corner));
  maps.push_back(std::make_unique<CubeMap>(6));
  maps.push_back(std::make_unique<CubeMap>(5, CubeLayout::HorizontalCross, CubeBasis::GL, TexelGrid::Corner));
  for (const auto& map : maps) {
    const int ti = map->width() / 3, tj = map->height() / 2;
    if (!(map->texel_solid_angle(ti, tj) > 0.0)) continue;
    const TexelProbe probe(*map, ti, tj, v, floor);
    const double omega = map->texel_solid_angle(ti, tj);
    EXPECT_LT(relative_error(probe.total_power(), v * omega + floor * (kFourPi - omega)), 1e-12);
    const Image img = rasterize(probe, *map);
    EXPECT_LT(relative_error(image_power(img, *map), probe.total_power()), 1e-6) << map->describe();
    for (int j = 0; j < img.height; ++j)
      for (int i = 0; i < img.width; ++i) {
        if (!(map->texel_solid_angle(i, j) > 0.0)) continue;
        const Vec3 want = (i == ti && j == tj) ? v : floor;
        for (int c = 0; c < 3; ++c)
          ASSERT_NEAR(img.at(i, j, c), want[c], 1e-6 * want[c]) << map->describe() << " " << i << "," << j;
      }
  }
}

TEST(ProbeRaster, TexelProbeIntoAnotherMapKeepsFlux) {
  const LatLongMap source(32, 16);
  const TexelProbe probe(source, 5, 3, Vec3(1e4), Vec3(0.5));
  const CubeMap cube(12);
  EXPECT_LT(relative_error(image_power(rasterize(probe, cube), cube), probe.total_power()), 1e-6);
  const LatLongMap other(45, 31);
  EXPECT_LT(relative_error(image_power(rasterize(probe, other), other), probe.total_power()), 1e-6);
}

TEST(ProbeRaster, MapFrameRotationMovesTheSun) {
  // Rasterizing into a map whose frame is rotated 90 deg about +Y: the sun at +X in the world appears where
  // the map's own frame has +Z... i.e. at map direction R^T (+X).
  const SunProbe sun(Vec3(1, 0, 0), radians(1.0), Vec3(1e3), Vec3(0.0));
  RasterOptions opt;
  opt.map_to_world = Mat3(0, 0, 1, 0, 1, 0, -1, 0, 0);  // column-vector M: world = M map; M (0,0,1) = (1,0,0)
  ASSERT_LT((apply(opt.map_to_world, Vec3(0, 0, 1)) - Vec3(1, 0, 0)).length(), 1e-12);
  const LatLongMap map(64, 32);
  const Image img = rasterize(sun, map, opt);
  EXPECT_LT(relative_error(image_power(img, map), sun.total_power()), 1e-6);
  const Vec2 p = map.to_image(Vec3(0, 0, 1));
  EXPECT_GT(img.at(static_cast<int>(p.x), static_cast<int>(p.y), 0), 10.0f);
}

// A checker that counts its background evaluations.
class CountingChecker final : public Probe {
 public:
  CountingChecker(int n_theta, int n_phi) : checker_(n_theta, n_phi, Vec3(1.0), Vec3(0.0)) {}
  std::string describe() const override { return checker_.describe(); }
  Vec3 background(const Vec3& dir) const override {
    calls_.fetch_add(1, std::memory_order_relaxed);
    return checker_.background(dir);
  }
  Variation background_variation() const override { return checker_.background_variation(); }
  bool background_may_vary(const Vec3& dir, double radius) const override {
    return checker_.background_may_vary(dir, radius);
  }
  double discontinuity_length() const override { return checker_.discontinuity_length(); }
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override {
    return checker_.integrate_latlong(u0, u1, v0, v1, integral);
  }
  Vec3 total_power() const override { return checker_.total_power(); }
  long calls() const { return calls_.load(); }

 private:
  CheckerProbe checker_;
  mutable std::atomic<long> calls_{0};
};

TEST(ProbeClosedForm, CheckerDiscontinuityLength) {
  // Parallels 2 pi sin(k pi / 4), k = 1..3, and 8 meridians of length pi.
  const double parallels = kTwoPi * (2.0 * std::sin(kPi / 4.0) + 1.0);
  EXPECT_NEAR(CheckerProbe(4, 8, Vec3(1), Vec3(0)).discontinuity_length(), parallels + 8.0 * kPi, 1e-12);
  // An odd number of columns: the seam joins two cells of one colour.
  EXPECT_NEAR(CheckerProbe(4, 7, Vec3(1), Vec3(0)).discontinuity_length(), parallels + 6.0 * kPi, 1e-12);
  EXPECT_NEAR(CheckerProbe(1, 2, Vec3(1), Vec3(0)).discontinuity_length(), 2.0 * kPi, 1e-12);
  EXPECT_EQ(CheckerProbe(1, 1, Vec3(1), Vec3(0)).discontinuity_length(), 0.0);
  EXPECT_EQ(CheckerProbe(4, 8, Vec3(1), Vec3(1)).discontinuity_length(), 0.0);
  EXPECT_EQ(ConstantProbe(Vec3(1)).discontinuity_length(), 0.0);
}

TEST(ProbeRaster, EdgeEvaluationsEstimateTheWork) {
  // The estimate against the background evaluations rasterize() makes beyond one per texel, on maps where
  // the cells' edges are what costs: within a factor of 2 either way (the last case: cells far finer than texels).
  struct Case {
    Kind kind;
    int n, n_theta, n_phi;
    double edge_radius_deg = 0.25;
  };
  for (const Case& c :
       {Case{Kind::CubeMap, 32, 6, 100}, Case{Kind::CubeMap, 32, 100, 6}, Case{Kind::MirrorBall, 64, 6, 100},
        Case{Kind::Octahedral, 64, 30, 30}, Case{Kind::HEALPix, 16, 6, 100}, Case{Kind::CubeMap, 8, 3, 1000, 1.0}}) {
    ParamSpec spec;
    spec.kind = c.kind;
    natural_image_size(c.kind, c.n, CubeLayout::VerticalStrip, spec.width, spec.height);
    const auto map = make_parameterization(spec);
    const CountingChecker probe(c.n_theta, c.n_phi);
    RasterOptions options;
    options.edge_radius = radians(c.edge_radius_deg);
    (void)rasterize(probe, *map, options);
    const double texels = double(map->width()) * map->height();
    const double estimate = edge_evaluations(probe, *map, options);
    const double beyond = double(probe.calls()) - texels;
    EXPECT_GT(estimate, beyond / 2.0) << map->describe() << ", " << c.n_theta << " x " << c.n_phi << " cells";
    EXPECT_LT(estimate, beyond * 2.0) << map->describe() << ", " << c.n_theta << " x " << c.n_phi << " cells";
  }
  // Exact lat-long integrals sample nothing; a rotated frame samples.
  const LatLongMap latlong(64, 32);
  const CountingChecker probe(6, 300);
  EXPECT_EQ(edge_evaluations(probe, latlong), 0.0);
  RasterOptions rotated;
  rotated.map_to_world = rotation_from_euler_degrees(30.0, 0.0, 0.0);
  EXPECT_GT(edge_evaluations(probe, latlong, rotated), 0.0);
}

TEST(ProbeRaster, DeterministicAcrossThreadCounts) {
  const OutdoorProbe probe;
  const LatLongMap map(128, 64);
  const Image many = rasterize(probe, map);
  Image one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = rasterize(probe, map);
  }
  EXPECT_EQ(many.pixels, one.pixels);
}

TEST(ProbeRaster, LuminanceAndExtraChannels) {
  const ConstantProbe probe(Vec3(1.0, 2.0, 4.0));
  const LatLongMap map(8, 4);
  Image y(8, 4, 1);
  rasterize_into(probe, map, y);
  EXPECT_NEAR(y.at(3, 2, 0), 0.2126 + 0.7152 * 2 + 0.0722 * 4, 1e-6);
  Image wrong(9, 4, 3);
  EXPECT_THROW(rasterize_into(probe, map, wrong), Error);
}

// --- the default probe ----------------------------------------------------------------------------------------

TEST(DefaultProbe, PlausibleValuesAndOrientation) {
  const std::unique_ptr<Probe> probe = make_default_probe();
  const auto* outdoor = dynamic_cast<const OutdoorProbe*>(probe.get());
  ASSERT_NE(outdoor, nullptr);
  for (const Size& s : {Size{256, 128}, Size{1000, 500}}) {
    const LatLongMap map(s.w, s.h);
    const Image img = rasterize(*probe, map);
    int bi = 0, bj = 0;
    double sky_sum = 0.0, ground_sum = 0.0;
    for (int j = 0; j < img.height; ++j)
      for (int i = 0; i < img.width; ++i) {
        for (int c = 0; c < 3; ++c) {
          const float v = img.at(i, j, c);
          ASSERT_TRUE(std::isfinite(v) && v >= 0.0f) << i << "," << j;
        }
        if (img.at(i, j, 1) > img.at(bi, bj, 1)) bi = i, bj = j;
        (j < img.height / 2 ? sky_sum : ground_sum) += img.at(i, j, 1);
      }
    EXPECT_GT(sky_sum, 3.0 * ground_sum);
    // The brightest texel sees the sun, at elevation 35 deg and azimuth 40 deg.
    const Vec3 sun = direction_from_elevation_azimuth(radians(35.0), radians(40.0));
    EXPECT_LT((outdoor->sun_direction() - sun).length(), 1e-12);
    const Vec2 p = map.to_image(sun);
    EXPECT_EQ(bi, static_cast<int>(p.x)) << s.w;
    EXPECT_EQ(bj, static_cast<int>(p.y)) << s.w;
    EXPECT_GT(img.at(bi, bj, 1), 1000.0f);
  }
  // Sun radiance ~3e4 x the sky.
  const Vec3 sun_dir = outdoor->sun_direction();
  EXPECT_GT(probe->radiance(sun_dir).y / probe->radiance(Vec3(0, 1, 0)).y, 1e4);
  // Clear sky (no clouds): blue zenith, brighter and whiter horizon, values ~0.2 .. 2.
  OutdoorSettings clear;
  clear.cloud_cover = 0.0;
  const OutdoorProbe clear_sky(clear);
  const Vec3 zenith = clear_sky.radiance(Vec3(0, 1, 0));
  const Vec3 horizon = clear_sky.radiance(direction_from_elevation_azimuth(radians(8.0), radians(-150.0)));
  EXPECT_GT(zenith.z, 2.0 * zenith.x);
  EXPECT_GT(horizon.x + horizon.y + horizon.z, 2.0 * (zenith.x + zenith.y + zenith.z));
  for (const Vec3& v : {zenith, horizon})
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(v[c] > 0.1 && v[c] < 2.5) << c;
  // Markers: red at +X, green at +Z, blue at -X, 3 deg above the horizon.
  auto marker = [&](double azimuth_deg) {
    return probe->radiance(direction_from_elevation_azimuth(radians(3.0), radians(azimuth_deg)));
  };
  const Vec3 red = marker(90.0), green = marker(0.0), blue = marker(-90.0);
  EXPECT_GT(red.x, 3.0 * std::max(red.y, red.z));
  EXPECT_GT(green.y, 3.0 * std::max(green.x, green.z));
  EXPECT_GT(blue.z, 3.0 * std::max(blue.x, blue.y));
  // Ground is darker and brownish (R > G > B).
  const Vec3 ground = probe->radiance(Vec3(0.1, -1.0, 0.3).normalized());
  EXPECT_LT(ground.y, 0.3);
  EXPECT_GT(ground.x, ground.y);
  EXPECT_GT(ground.y, ground.z);
  // Silhouettes: dark at 1 deg above the horizon in the mountain range and along most of the skyline.
  EXPECT_LT(probe->radiance(direction_from_elevation_azimuth(radians(1.0), radians(-45.0))).y, 0.5);
  int dark_city = 0;
  for (double az = 110.0; az < 170.0; az += 0.5)
    dark_city += probe->radiance(direction_from_elevation_azimuth(radians(0.5), radians(az))).y < 0.1;
  EXPECT_GT(dark_city, 40);  // of 120 samples
}

TEST(DefaultProbe, PowerIsConsistentAndDeterministic) {
  const OutdoorProbe a, b;
  EXPECT_FALSE(a.power_is_closed_form());
  const Vec3 pa = a.total_power();
  EXPECT_EQ(pa, b.total_power());
  const LatLongMap map(200, 100);
  EXPECT_LT(relative_error(image_power(rasterize(a, map), map), pa), 2e-3);
  // The sun is exact whatever the resolution: its flux alone is 3.2e4 x pi (0.27 deg)^2 ~ 2.2 in R.
  for (int c = 0; c < 3; ++c) EXPECT_GT(pa[c], a.settings().sun_radiance[c] * cap_solid_angle(radians(0.27)));
}

// --- envprobe -------------------------------------------------------------------------------------------------

std::string run(const std::string& command, int& status) {
  std::string out;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) {
    status = -1;
    return out;
  }
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
  const int rc = pclose(pipe);
  status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  return out;
}

const std::string kEnvprobe = std::string(ENVKIT_BIN_DIR) + "/envprobe";

class EnvprobeCli : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(std::filesystem::exists(kEnvprobe)) << kEnvprobe << " not built (it is part of the default build)";
    dir_ = std::filesystem::temp_directory_path() / ("envkit_test_probes_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty()) std::filesystem::remove_all(dir_, ec);
  }
  std::filesystem::path dir_;
};

TEST_F(EnvprobeCli, HelpAndBadArguments) {
  int status = 0;
  const std::string help = run(kEnvprobe + " --help", status);
  EXPECT_EQ(status, 0);
  EXPECT_NE(help.find("Examples"), std::string::npos);
  const std::string bad_size = run(kEnvprobe + " constant -o " + (dir_ / "x.exr").string() + " --size 0x5", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(bad_size.find("size"), std::string::npos);
  const std::string bad_texel =
      run(kEnvprobe + " texel -o " + (dir_ / "x.exr").string() + " --size 8x4 --texel 9,1", status);
  EXPECT_NE(status, 0);
  EXPECT_NE(bad_texel.find("texel"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.exr"));
}

#if __has_include(<envkit/io/image_io.h>)
TEST_F(EnvprobeCli, WritesMapAndReportsPower) {
  int status = 0;
  const std::string out = (dir_ / "sun.exr").string();
  const std::string json = run(kEnvprobe + " sun -o " + out +
                                   " --size 64x32 --radiance 1e5 --sky 0.1 --radius-deg 0.05 --elevation-deg 30"
                                   " --azimuth-deg 10 --json",
                               status);
  ASSERT_EQ(status, 0) << json;
  const SunProbe sun(direction_from_elevation_azimuth(radians(30.0), radians(10.0)), radians(0.05), Vec3(1e5),
                     Vec3(0.1));
  const nlohmann::json report = nlohmann::json::parse(json);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(report["total_power"][c].get<double>(), sun.total_power()[c], 1e-12 * sun.total_power()[c]);
    EXPECT_NEAR(report["map_power"][c].get<double>(), sun.total_power()[c], 1e-6 * sun.total_power()[c]);
  }
  EXPECT_EQ(report["parameterization"], "latlong");
  EXPECT_TRUE(report["power_closed_form"].get<bool>());
  const Image img = read_image(out);
  ASSERT_EQ(img.width, 64);
  ASSERT_EQ(img.height, 32);
  EXPECT_EQ(img.metadata.at("envkit:parameterization"), "latlong");
  const LatLongMap map(64, 32);
  EXPECT_LT(relative_error(image_power(img, map), sun.total_power()), 1e-6);
}

TEST_F(EnvprobeCli, CubeOutput) {
  int status = 0;
  const std::string out = (dir_ / "checker.exr").string();
  const std::string text = run(kEnvprobe + " checker -o " + out + " --param cube --size 16 --cells 4,8", status);
  ASSERT_EQ(status, 0) << text;
  const Image img = read_image(out);
  EXPECT_EQ(img.width, 16);
  EXPECT_EQ(img.height, 96);
  EXPECT_EQ(img.metadata.at("envkit:parameterization"), "cube");
  // -q: the map is written, nothing is printed.
  std::filesystem::remove(out);
  const std::string quiet = run(kEnvprobe + " checker -o " + out + " --param cube --size 16 -q", status);
  ASSERT_EQ(status, 0) << quiet;
  EXPECT_EQ(quiet, "");
  EXPECT_TRUE(std::filesystem::exists(out));
}
#endif

}  // namespace
}  // namespace envkit::probes
