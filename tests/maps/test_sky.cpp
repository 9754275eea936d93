// The sky formats (skylibs' skylatlong and skyangular): exact texel solid angles summing to 2 pi, known directions
// on known texels, round trips, skylibs' own formulas, and envconvert/envinfo reading and writing them.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/skyangular.h>
#include <envkit/maps/skylatlong.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "cli_support.h"

using namespace envkit;
namespace fs = std::filesystem;

namespace {

fs::path scratch_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("envkit_test_sky_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

// A uniform direction of the upper hemisphere (y >= 0).
Vec3 upper_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double y = u(rng), phi = kTwoPi * u(rng), s = std::sqrt(std::max(0.0, 1.0 - y * y));
  return Vec3(s * std::cos(phi), y, s * std::sin(phi));
}

std::vector<std::pair<int, int>> sky_latlong_sizes() {
  return {{1, 1}, {4, 1}, {3, 2}, {7, 3}, {64, 16}, {4096, 1024}};
}
std::vector<int> sky_angular_sizes() { return {1, 2, 3, 9, 64, 1023}; }

std::vector<std::unique_ptr<Parameterization>> all_sky_maps() {
  std::vector<std::unique_ptr<Parameterization>> maps;
  for (auto [w, h] : sky_latlong_sizes()) maps.push_back(std::make_unique<SkyLatLongMap>(w, h));
  for (int n : sky_angular_sizes()) maps.push_back(std::make_unique<SkyAngularMap>(n, n));
  maps.push_back(std::make_unique<SkyAngularMap>(7, 5));  // not square: the disk inscribed in the height
  return maps;
}

// skylibs' own formulas (envmap/projections.py: world2skylatlong, world2skyangular), in skylibs' world, which is
// envkit's turned half a turn about +Y: (x, y, z) skylibs = (-x, y, -z) envkit. They give (u, v) in [0, 1]^2 of
// the image's width and height.
Vec2 skylibs_skylatlong_uv(const Vec3& envkit_dir) {
  const double x = -envkit_dir.x, y = envkit_dir.y, z = -envkit_dir.z;
  return Vec2((1.0 + std::atan2(x, -z) / kPi) / 2.0, std::acos(y) / kPi * 2.0);
}
Vec2 skylibs_skyangular_uv(const Vec3& envkit_dir) {
  const double x = -envkit_dir.x, y = envkit_dir.y, z = -envkit_dir.z;
  const double theta = std::atan2(x, z), phi = std::atan2(std::hypot(x, z), y), r = phi / (kPi / 2.0);
  return Vec2(0.5 + r * std::sin(theta) / 2.0, 0.5 - r * std::cos(theta) / 2.0);
}

}  // namespace

TEST(SkyMaps, TexelSolidAnglesSumTo2Pi) {
  for (const auto& p : all_sky_maps()) {
    std::vector<float> omega(static_cast<std::size_t>(p->width()) * p->height());
    EXPECT_NEAR(p->texel_solid_angles(omega) / kTwoPi, 1.0, 1e-9) << p->describe();
    EXPECT_NEAR(SolidAngleTable(*p).total() / kTwoPi, 1.0, 1e-9) << p->describe();
    // Texel by texel, as every other loop sees them.
    if (std::size_t(p->width()) * p->height() <= 100000) {
      double sum = 0.0;
      for (int j = 0; j < p->height(); ++j)
        for (int i = 0; i < p->width(); ++i) sum += p->texel_solid_angle(i, j);
      EXPECT_NEAR(sum / kTwoPi, 1.0, 1e-9) << p->describe();
    }
    EXPECT_NEAR(p->solid_angle(0, 0, p->width(), p->height()) / kTwoPi, 1.0, 1e-12) << p->describe();
    EXPECT_FALSE(p->covers_sphere()) << p->describe();
  }
}

// A sky lat-long's row is the band between its parallels, in the closed form written independently here: row j of
// H spans zenith angles [pi/2 j/H, pi/2 (j+1)/H] and each of its W texels is 2 pi / W of the band.
TEST(SkyMaps, SkyLatLongRowsAreBands) {
  const SkyLatLongMap map(12, 5);
  for (int j = 0; j < 5; ++j) {
    const double a = kPi / 2 * j / 5, b = kPi / 2 * (j + 1) / 5;
    for (int i = 0; i < 12; ++i)
      EXPECT_NEAR(map.texel_solid_angle(i, j), kTwoPi / 12 * (std::cos(a) - std::cos(b)), 1e-15) << i << "," << j;
  }
  // Any sub-rectangle: the same closed form over its own extent.
  const double x0 = 1.25, x1 = 7.5, y0 = 0.3, y1 = 4.9;
  EXPECT_NEAR(map.solid_angle(x0, y0, x1, y1),
              kTwoPi * (x1 - x0) / 12 * (std::cos(kPi / 2 * y0 / 5) - std::cos(kPi / 2 * y1 / 5)), 1e-14);
  // The fast paths' geometry: the 12 x 10 lat-long whose upper half this is, texel for texel.
  const LatLongMap* sphere = map.latlong_geometry();
  ASSERT_NE(sphere, nullptr);
  EXPECT_EQ(sphere->width(), 12);
  EXPECT_EQ(sphere->height(), 10);
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 12; ++i) {
      EXPECT_EQ(sphere->texel_solid_angle(i, j), map.texel_solid_angle(i, j));
      Vec3 a, b;
      ASSERT_TRUE(sphere->to_direction(Vec2(i + 0.5, j + 0.5), a) && map.to_direction(Vec2(i + 0.5, j + 0.5), b));
      EXPECT_EQ(angle_between(a, b), 0.0);
    }
  // Below the horizon there is nothing.
  EXPECT_EQ(map.solid_angle(0, 5, 12, 9), 0.0);
  EXPECT_DOUBLE_EQ(map.solid_angle(0, 4, 12, 9), map.solid_angle(0, 4, 12, 5));
}

// A rectangle of whole texels holds exactly the sum of its texels' solid angles.
TEST(SkyMaps, RectangleSolidAngleIsTheSumOfItsTexels) {
  for (const auto& p : all_sky_maps()) {
    const int W = p->width(), H = p->height();
    if (std::size_t(W) * H > 100000) continue;
    const int x0 = W / 5, x1 = std::max(x0 + 1, 3 * W / 4), y0 = H / 3, y1 = std::max(y0 + 1, H - H / 5);
    double sum = 0.0;
    for (int j = y0; j < y1; ++j)
      for (int i = x0; i < x1; ++i) sum += p->texel_solid_angle(i, j);
    EXPECT_NEAR(p->solid_angle(x0, y0, x1, y1), sum, 1e-12 * std::max(sum, 1.0)) << p->describe();
  }
}

// Zenith, and the horizon at azimuth 0 (+Z, envkit's azimuth is measured from +Z towards +X as on its lat-long) and
// at azimuth 90 (+X), land on known texels.
TEST(SkyMaps, KnownDirectionsOnKnownTexels) {
  const SkyLatLongMap ll(64, 16);
  Vec3 d;
  ASSERT_TRUE(ll.to_direction(Vec2(20.5, 0.0), d));
  EXPECT_LT(angle_between(d, Vec3(0, 1, 0)), 1e-12);
  EXPECT_NEAR(ll.to_image(Vec3(0, 1, 0)).y, 0.0, 1e-12);
  // The horizon is the bottom edge: +Z at u = 1/2, +X at u = 1/4, -X at u = 3/4, -Z at u = 0.
  const std::pair<Vec3, double> horizon[] = {
      {Vec3(0, 0, 1), 32.0}, {Vec3(1, 0, 0), 16.0}, {Vec3(-1, 0, 0), 48.0}, {Vec3(0, 0, -1), 0.0}};
  for (const auto& [dir, x] : horizon) {
    const Vec2 p = ll.to_image(dir);
    EXPECT_NEAR(p.x, x, 1e-9) << dir;
    EXPECT_NEAR(p.y, 16.0, 1e-9) << dir;
    EXPECT_EQ(static_cast<int>(p.y), 15) << dir;  // in the bottom row
    ASSERT_TRUE(ll.to_direction(Vec2(x, 16.0), d));
    EXPECT_LT(angle_between(d, dir), 1e-12) << dir;
  }
  // 45 degrees up towards +X: half way down the image.
  EXPECT_NEAR(ll.to_image(Vec3(1, 1, 0)).y, 8.0, 1e-12);
  EXPECT_NEAR(ll.to_image(Vec3(1, 1, 0)).x, 16.0, 1e-12);

  const SkyAngularMap ang(64, 64);
  ASSERT_TRUE(ang.to_direction(Vec2(32, 32), d));
  EXPECT_LT(angle_between(d, Vec3(0, 1, 0)), 1e-12);
  // Image right is -X, image up -Z: +Z on the bottom rim, +X on the left rim.
  const std::pair<Vec3, Vec2> rim[] = {{Vec3(0, 0, 1), Vec2(32, 64)},
                                       {Vec3(1, 0, 0), Vec2(0, 32)},
                                       {Vec3(-1, 0, 0), Vec2(64, 32)},
                                       {Vec3(0, 0, -1), Vec2(32, 0)}};
  for (const auto& [dir, pos] : rim) {
    const Vec2 p = ang.to_image(dir);
    EXPECT_NEAR(p.x, pos.x, 1e-9) << dir;
    EXPECT_NEAR(p.y, pos.y, 1e-9) << dir;
  }
  // 45 degrees up towards +Z: half way from the centre to the bottom rim (equidistant).
  const Vec2 p = ang.to_image(Vec3(0, 1, 1));
  EXPECT_NEAR(p.x, 32.0, 1e-12);
  EXPECT_NEAR(p.y, 48.0, 1e-12);
}

// Below the horizon nothing is seen: such directions map outside the image.
TEST(SkyMaps, DirectionsBelowTheHorizonMapOutside) {
  std::mt19937_64 rng(7);
  for (const auto& p : all_sky_maps())
    for (int k = 0; k < 100; ++k) {
      Vec3 d = upper_direction(rng);
      d.y = -std::max(d.y, 1e-9);
      const Vec2 q = p->to_image(d);
      EXPECT_TRUE(q.x < 0 || q.y < 0 || q.x > p->width() || q.y > p->height()) << p->describe() << " " << d;
    }
  // Outside the disk a sky angular texel holds no data.
  const SkyAngularMap ang(8, 8);
  EXPECT_EQ(ang.texel_solid_angle(0, 0), 0.0);
  EXPECT_TRUE(ang.has_blank_texels());
}

TEST(SkyMaps, DirectionTexelDirectionRoundTrip) {
  std::mt19937_64 rng(11);
  for (const auto& p : all_sky_maps()) {
    for (int k = 0; k < 2000; ++k) {
      const Vec3 d = upper_direction(rng);
      const Vec2 q = p->to_image(d);
      ASSERT_TRUE(q.x >= 0 && q.y >= 0 && q.x <= p->width() && q.y <= p->height()) << p->describe() << " " << d;
      Vec3 back;
      ASSERT_TRUE(p->to_direction(q, back)) << p->describe();
      ASSERT_LT(angle_between(d, back), 1e-9) << p->describe() << " " << d;
    }
    // Texel centres that hold data come back to their own texel.
    for (int j = 0; j < std::min(p->height(), 40); ++j)
      for (int i = 0; i < std::min(p->width(), 40); ++i) {
        Vec3 d;
        if (!p->to_direction(Vec2(i + 0.5, j + 0.5), d)) continue;
        const Vec2 q = p->to_image(d);
        ASSERT_NEAR(q.x, i + 0.5, 1e-6) << p->describe();
        ASSERT_NEAR(q.y, j + 0.5, 1e-6) << p->describe();
      }
  }
}

// skylibs' world2skylatlong and world2skyangular put every upper direction where envkit does (u W, v H).
TEST(SkyMaps, MatchSkylibsFormulas) {
  const SkyLatLongMap ll(400, 100);
  const SkyAngularMap ang(300, 300);
  std::mt19937_64 rng(13);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 d = upper_direction(rng);
    const Vec2 a = skylibs_skylatlong_uv(d), p = ll.to_image(d);
    if (a.x > 1e-9 && a.x < 1 - 1e-9) {  // away from the seam
      ASSERT_NEAR(p.x, a.x * 400, 1e-8) << d;
    }
    ASSERT_NEAR(p.y, a.y * 100, 1e-8) << d;
    const Vec2 b = skylibs_skyangular_uv(d), q = ang.to_image(d);
    ASSERT_NEAR(q.x, b.x * 300, 1e-8) << d;
    ASSERT_NEAR(q.y, b.y * 300, 1e-8) << d;
  }
}

// The factory and the frames: natural size 4N x N and N x N, the same frame as a lat-long under every convention.
TEST(SkyMaps, FactoryAndConventions) {
  const ParamSpec s = spec_for(Kind::SkyLatLong, 32, convention("envkit"));
  EXPECT_EQ(s.width, 128);
  EXPECT_EQ(s.height, 32);
  const ParamSpec a = spec_for(Kind::SkyAngular, 32, convention("envkit"));
  EXPECT_EQ(a.width, 32);
  EXPECT_EQ(a.height, 32);
  EXPECT_EQ(make_parameterization(s)->kind(), Kind::SkyLatLong);
  EXPECT_EQ(make_parameterization(a)->kind(), Kind::SkyAngular);
  EXPECT_EQ(parse_kind("SkyLatLong"), Kind::SkyLatLong);
  EXPECT_EQ(kind_name(parse_kind("skyangular")), "skyangular");
  for (const std::string& name : convention_names()) {
    const Convention& c = convention(name);
    for (Kind k : {Kind::SkyLatLong, Kind::SkyAngular})
      EXPECT_TRUE(c.frame(k) == c.frame(Kind::LatLong)) << name << " " << kind_name(k);
  }
}

// envconvert: latlong -> skylatlong -> latlong keeps the upper hemisphere's power (area filter) and writes zero
// coverage below the horizon; the sky files carry their kind in metadata, envinfo names it, and a 4:1 image needs
// --from.
TEST(SkyMaps, EnvconvertRoundTripKeepsTheUpperHemispheresPower) {
  const fs::path dir = scratch_dir("cli");
  const int W = 128, H = 64;
  const LatLongMap ll(W, H);
  Image img(W, H, 3);
  img.channel_names = {"R", "G", "B"};
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      Vec3 d;
      ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = float(1.0 + 0.5 * d[c] + (i == 40 && j == 10 ? 500.0 : 0.0));
    }
  double upper = 0.0;  // red power above the horizon (rows 0..H/2-1: the horizon is a row edge)
  for (int j = 0; j < H / 2; ++j)
    for (int i = 0; i < W; ++i) upper += double(img.at(i, j, 0)) * ll.texel_solid_angle(i, j);
  EnvMap m;
  m.image = img;
  m.param = std::make_unique<LatLongMap>(W, H);
  const std::string src = (dir / "src.exr").string();
  save_envmap(src, m);

  // The area filter's power bound: the project's for every pair of maps is 1e-3 (test_resample); the lat-long grids
  // keep it to 1e-4, the disk's rim (bilinear taps beyond it dropped) to 1e-3 on the way back.
  struct Case {
    std::string kind, size;
    int width, height;
    double back_tolerance;
  };
  for (const Case& c : {Case{"skylatlong", "24", 96, 24, 1e-4}, Case{"skylatlong", "", 128, 32, 1e-4},
                        Case{"skyangular", "48", 48, 48, 1e-3}}) {
    SCOPED_TRACE(c.kind + " " + c.size);
    const std::string sky = (dir / ("sky_" + c.kind + ".exr")).string(), back = (dir / "back.exr").string();
    std::vector<std::string> args = {src, "-o", sky, "--to", c.kind, "-q"};
    if (!c.size.empty()) args.insert(args.end(), {"--size", c.size});
    auto r = test::run_tool("envconvert", args, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    const EnvMap s = load_envmap(sky);
    EXPECT_EQ(kind_name(s.param->kind()), c.kind);
    EXPECT_EQ(s.image.width, c.width);
    EXPECT_EQ(s.image.height, c.height);
    EXPECT_NEAR(total_power(s.image, *s.param)[0] / upper, 1.0, 1e-4);

    r = test::run_tool("envinfo", {sky}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find(c.kind), std::string::npos) << r.out;

    r = test::run_tool("envconvert", {sky, "-o", back, "--to", "latlong", "--size", "64", "-q"}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    const EnvMap b = load_envmap(back);
    ASSERT_EQ(b.image.channels, 4);  // coverage alpha added
    ASSERT_EQ(b.image.alpha_channel, 3);
    double back_upper = 0.0;
    for (int j = 0; j < H; ++j)
      for (int i = 0; i < W; ++i) {
        if (j >= H / 2) {
          ASSERT_EQ(b.image.at(i, j, 3), 0.0f) << i << "," << j;
          ASSERT_EQ(b.image.at(i, j, 0), 0.0f) << i << "," << j;
        } else if (c.kind == "skylatlong") {
          ASSERT_NEAR(b.image.at(i, j, 3), 1.0f, 1e-6) << i << "," << j;
        }
        back_upper += double(b.image.at(i, j, 0)) * b.param->texel_solid_angle(i, j);
      }
    EXPECT_NEAR(back_upper / upper, 1.0, c.back_tolerance);
    fs::remove(back);
  }

  // A 4:1 image without metadata is not guessed: --from skylatlong reads it.
  Image strip(64, 16, 3);
  strip.channel_names = {"R", "G", "B"};
  const std::string untagged = (dir / "strip.exr").string();
  write_image(untagged, strip);
  auto r = test::run_tool("envconvert", {untagged, "-o", (dir / "x.exr").string(), "--to", "latlong"}, dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("pass --from skylatlong"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.exr"));
  r = test::run_tool("envconvert",
                     {untagged, "-o", (dir / "x.exr").string(), "--to", "latlong", "--from", "skylatlong", "-q"}, dir);
  EXPECT_EQ(r.code, 0) << r.err;
  fs::remove_all(dir);
}
