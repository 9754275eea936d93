// Sun detection: analytic suns rasterised into lat-long, cube and octahedral maps (direction, power, size), a sun
// across a cube edge, maps without a sun, a clipped sun, and envinfo's report of it.
#include <envkit/core/vec.h>
#include <envkit/envmap/sun.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/probes.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_support.h"

using namespace envkit;
namespace fs = std::filesystem;

namespace {

double degrees_between(const Vec3& a, const Vec3& b) {
  return safe_acos(a.normalized() ^ b.normalized()) * 180.0 / kPi;
}

EnvMap rasterized(const probes::Probe& probe, std::unique_ptr<Parameterization> param) {
  EnvMap map;
  map.image = probes::rasterize(probe, *param);
  map.param = std::move(param);
  return map;
}

// A sun of radius `radius_deg` and radiance 1e5 over a sky of 0.05: the disk's own power (sun minus the sky it
// replaces) is what a detector must find, plus the sky inside the texels it takes.
struct SunCase {
  Vec3 direction;
  double radius_deg;
};

void expect_found(const EnvMap& map, const SunCase& c, const char* what) {
  SCOPED_TRACE(what);
  const std::optional<SunEstimate> sun = detect_sun(map);
  ASSERT_TRUE(sun.has_value());
  // The flux centroid of the texels: well within a texel of the true centre.
  const double texel_deg = std::sqrt(kFourPi / double(map.image.texel_count())) * 180.0 / kPi;
  EXPECT_LT(degrees_between(sun->direction, c.direction), 0.25 * texel_deg);
  const double alpha = c.radius_deg * kPi / 180.0;
  const double disk = kTwoPi * (1.0 - std::cos(alpha));
  const double expected = (1e5 - 0.05) * disk + 0.05 * sun->solid_angle;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(sun->power[std::size_t(k)], expected, 2e-3 * expected) << k;
  // The region is the disk plus its partly covered edge texels.
  EXPECT_GE(sun->solid_angle, disk * (1.0 - 1e-3));
  EXPECT_LE(sun->angular_radius * 180.0 / kPi, c.radius_deg + 2.0 * texel_deg);
  EXPECT_NEAR(sun->radiance[0] * sun->solid_angle, sun->power[0], 1e-9 * sun->power[0]);
  EXPECT_GT(sun->power_share, 0.9);
  EXPECT_FALSE(sun->clipped);
  // The region's texels: as many as it counts, ascending, each brighter than the sky.
  ASSERT_EQ(sun->region.size(), std::size_t(sun->texels));
  for (std::size_t k = 0; k < sun->region.size(); ++k) {
    if (k > 0) {
      EXPECT_LT(sun->region[k - 1], sun->region[k]);
    }
    EXPECT_GT(map.image.pixels[sun->region[k] * std::size_t(map.image.channels)], 1.0f);
  }
}

TEST(Sun, FoundInLatLongCubeAndOctahedralMaps) {
  for (const SunCase& c : {SunCase{Vec3(0.5, 0.6, 0.62), 0.5}, SunCase{Vec3(-0.2, 0.1, -0.97), 1.5},
                           SunCase{Vec3(0.7, 0.7, 0.1), 0.8} /* across the +X/+Y cube edge */}) {
    const probes::SunProbe probe(c.direction, c.radius_deg * kPi / 180.0, Vec3(1e5), Vec3(0.05));
    expect_found(rasterized(probe, std::make_unique<LatLongMap>(512, 256)), c, "latlong 512");
    expect_found(rasterized(probe, std::make_unique<CubeMap>(128, CubeLayout::VerticalStrip, CubeBasis::GL)), c,
                 "cube 128");
    expect_found(rasterized(probe, std::make_unique<OctahedralMap>(256)), c, "octahedral 256");
  }
}

TEST(Sun, TheDefaultProbesSunIsWhereItsSettingsPutIt) {
  const probes::OutdoorProbe probe;
  const EnvMap map = rasterized(probe, std::make_unique<LatLongMap>(1024, 512));
  const std::optional<SunEstimate> sun = detect_sun(map);
  ASSERT_TRUE(sun.has_value());
  EXPECT_LT(degrees_between(sun->direction, probe.sun_direction()), 0.05);
  // Its power: the disk's excess over the sky (3.2e4, 3.0e4, 2.7e4 over a disk of 0.27 degrees) plus the sky
  // under the region, which is a few per mille of it.
  const double disk = kTwoPi * (1.0 - std::cos(0.27 * kPi / 180.0));
  EXPECT_NEAR(sun->power[0], 3.2e4 * disk, 0.01 * 3.2e4 * disk);
  EXPECT_NEAR(sun->power[2], 2.7e4 * disk, 0.01 * 2.7e4 * disk);
}

TEST(Sun, NoneInMapsWithoutOne) {
  // Constant, a smooth sky, and a bright but broad blob (20 degrees: a lamp-lit wall, not a sun).
  const probes::ConstantProbe constant(Vec3(1.0));
  EXPECT_FALSE(detect_sun(rasterized(constant, std::make_unique<LatLongMap>(256, 128))).has_value());
  const probes::GradientProbe gradient(Vec3(0.2), Vec3(1.0), probes::GradientProbe::Form::Quadratic);
  EXPECT_FALSE(detect_sun(rasterized(gradient, std::make_unique<LatLongMap>(256, 128))).has_value());
  const probes::SunProbe broad(Vec3(0, 1, 0), 20.0 * kPi / 180.0, Vec3(1e5), Vec3(0.05));
  EXPECT_FALSE(detect_sun(rasterized(broad, std::make_unique<LatLongMap>(256, 128))).has_value());
  // A faint small spot: bright against the sky but with a negligible share of the light.
  const probes::SunProbe faint(Vec3(0, 1, 0), 0.5 * kPi / 180.0, Vec3(200.0), Vec3(1.0));
  EXPECT_FALSE(detect_sun(rasterized(faint, std::make_unique<LatLongMap>(256, 128))).has_value());
}

TEST(Sun, ClippedSunIsReported) {
  const probes::SunProbe probe(Vec3(0.3, 0.5, 0.8), 1.5 * kPi / 180.0, Vec3(1e5), Vec3(0.05));
  EnvMap map = rasterized(probe, std::make_unique<LatLongMap>(512, 256));
  for (float& v : map.image.pixels) v = std::min(v, 200.0f);  // a camera that saturated at 200
  const std::optional<SunEstimate> sun = detect_sun(map);
  ASSERT_TRUE(sun.has_value());
  EXPECT_TRUE(sun->clipped);
  EXPECT_GE(sun->clipped_texels, 3);
}

TEST(Sun, NonFiniteAndNegativeTexelsCountAsZero) {
  const probes::SunProbe probe(Vec3(0.3, 0.5, 0.8), 1.0 * kPi / 180.0, Vec3(1e5), Vec3(0.05));
  EnvMap map = rasterized(probe, std::make_unique<LatLongMap>(256, 128));
  map.image.at(3, 100, 0) = std::numeric_limits<float>::quiet_NaN();
  map.image.at(4, 100, 1) = -1e9f;
  map.image.at(5, 100, 2) = std::numeric_limits<float>::infinity();  // an Inf is not a sun either: it is 0 here
  const std::optional<SunEstimate> sun = detect_sun(map);
  ASSERT_TRUE(sun.has_value());
  EXPECT_LT(degrees_between(sun->direction, probe.direction()), 0.2);
  EXPECT_TRUE(std::isfinite(sun->power[0]) && std::isfinite(sun->power[1]) && std::isfinite(sun->power[2]));
}

class SunCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_sun_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(SunCli, EnvinfoReportsTheSunAndWarnsWhenItIsClipped) {
  const std::string sky = (dir_ / "sky.exr").string();
  ASSERT_EQ(test::run_tool("envprobe", {"default", "-o", sky, "--size", "512x256"}, dir_).code, 0);
  const test::CommandResult text = test::run_tool("envinfo", {sky}, dir_);
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_NE(text.out.find("\nsun               elevation 34.9"), std::string::npos) << text.out;
  const test::CommandResult js = test::run_tool("envinfo", {sky, "--json"}, dir_);
  ASSERT_EQ(js.code, 0) << js.err;
  const nlohmann::json j = nlohmann::json::parse(js.out);
  EXPECT_NEAR(j["sun"]["elevation_deg"].get<double>(), 35.0, 0.3);
  EXPECT_NEAR(j["sun"]["azimuth_deg"].get<double>(), 40.0, 0.3);
  EXPECT_FALSE(j["sun"]["clipped"].get<bool>());
  EXPECT_TRUE(js.err_lines().empty()) << js.err;

  const std::string flat = (dir_ / "flat.exr").string();
  ASSERT_EQ(test::run_tool("envprobe",
                           {"sun", "-o", flat, "--size", "512x256", "--radiance", "1e5", "--radius-deg", "1.5"}, dir_)
                .code,
            0);
  Image image = read_image(flat);
  for (float& v : image.pixels) v = std::min(v, 300.0f);
  write_image(flat, image);
  const test::CommandResult clipped = test::run_tool("envinfo", {flat}, dir_);
  ASSERT_EQ(clipped.code, 0) << clipped.err;
  ASSERT_EQ(clipped.err_lines().size(), 1u) << clipped.err;
  EXPECT_NE(clipped.err.find(flat), std::string::npos);
  EXPECT_NE(clipped.err.find("clipped"), std::string::npos);

  const std::string plain = (dir_ / "plain.exr").string();
  ASSERT_EQ(test::run_tool("envprobe", {"gradient", "-o", plain, "--size", "128x64"}, dir_).code, 0);
  const nlohmann::json none = nlohmann::json::parse(test::run_tool("envinfo", {plain, "--json"}, dir_).out);
  EXPECT_TRUE(none["sun"].is_null());
}

}  // namespace
