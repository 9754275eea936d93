// Merging captures (merge.h, envmerge): captures cut from the built-in analytic
// outdoor probe (fisheyes, mirror balls 90 degrees apart, perspective views)
// merge back into the probe's lat-long; masks drop a "photographer", exposures
// undo darker shots, and the uncovered solid angle matches the closed form.
#include "cli_support.h"

#include <envkit/envmap.h>
#include <envkit/fisheye.h>
#include <envkit/latlong.h>
#include <envkit/merge.h>
#include <envkit/mirrorball.h>
#include <envkit/perspective.h>
#include <envkit/probes.h>
#include <envkit/resample.h>
#include <envkit/solid_angle_table.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

namespace fs = std::filesystem;
using namespace envkit;

namespace {

const Mat3 kId = identity3();

// The default probe on a fine lat-long, the source every capture is cut from.
const Image &reference() {
  static const Image ref =
      probes::rasterize(*probes::make_default_probe(), LatLongMap(1024, 512));
  return ref;
}

Capture cut(std::unique_ptr<Parameterization> param, const Mat3 &rotation = kId,
            double scale = 1.0) {
  const LatLongMap ll(1024, 512);
  Capture c;
  c.map.param = std::move(param);
  c.map.rotation = rotation;
  c.map.image =
      resample({reference(), ll, kId}, *c.map.param, c.map.to_world());
  for (float &v : c.map.image.pixels)
    v = float(v * scale);
  if (c.map.image.alpha_channel >= 0) // coverage is not light: keep it
    for (int j = 0; j < c.map.image.height; ++j)
      for (int i = 0; i < c.map.image.width; ++i)
        c.map.image.at(i, j, c.map.image.alpha_channel) =
            float(c.map.image.at(i, j, c.map.image.alpha_channel) / scale);
  c.name = c.map.param->describe();
  return c;
}

ViewParams fisheye_view(double yaw, double fov) {
  ViewParams v;
  v.forward = direction_from_yaw_pitch(yaw, 0);
  v.fov_degrees = fov;
  v.lens = Lens::Equisolid;
  return v;
}

// Solid-angle weighted relative RMS of the colour over texels the merge covers
// fully, against the reference resampled to the same grid; texels within 3
// degrees of the sun are left out (its edge is a step a few texels wide).
double merged_error(const Image &merged, const LatLongMap &ll) {
  const Image ref =
      resample({reference(), LatLongMap(1024, 512), kId}, ll, kId);
  const SolidAngleTable omega(ll);
  const probes::OutdoorProbe probe;
  double num = 0, den = 0;
  for (int j = 0; j < ll.height(); ++j)
    for (int i = 0; i < ll.width(); ++i) {
      if (merged.at(i, j, 3) < 0.999f)
        continue;
      Vec3 d;
      ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
      if (angle_between(d, probe.sun_direction()) < 3 * kPi / 180)
        continue;
      for (int c = 0; c < 3; ++c) {
        const double e = merged.at(i, j, c) - ref.at(i, j, c);
        num += omega(i, j) * e * e;
        den += omega(i, j) * double(ref.at(i, j, c)) * ref.at(i, j, c);
      }
    }
  return std::sqrt(num / den);
}

} // namespace

// Two 200-degree equisolid fisheyes back to back see everything; merged they
// give the probe back.
TEST(Merge, TwoFisheyesBackToBackGiveTheProbe) {
  std::vector<Capture> captures;
  captures.push_back(
      cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(0, 200))));
  captures.push_back(
      cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(180, 200))));
  const LatLongMap ll(128, 64);
  MergeReport report;
  const Image merged = merge_captures(captures, ll, kId, &report);
  EXPECT_LT(report.uncovered_solid_angle, 1e-3);
  EXPECT_LT(merged_error(merged, ll), 0.02);
  ASSERT_EQ(report.weight_share.size(), 2u);
  EXPECT_NEAR(report.weight_share[0], 0.5, 0.05);
  // Each sees its 200-degree cap: 2 pi (1 - cos 100 deg).
  for (double s : report.covered_solid_angle)
    EXPECT_NEAR(s, kTwoPi * (1 - std::cos(100 * kPi / 180)), 0.02 * s);
  // A back shot one stop and a half darker (x 0.35), merged with exposure 1 /
  // 0.35, gives the same map.
  std::vector<Capture> dark;
  dark.push_back(
      cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(0, 200))));
  dark.push_back(
      cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(180, 200)), kId,
          0.35));
  dark[1].exposure = 1 / 0.35;
  const Image again = merge_captures(dark, ll, kId);
  double worst = 0;
  for (std::size_t t = 0; t < again.pixels.size(); ++t)
    worst =
        std::max(worst, double(std::abs(again.pixels[t] - merged.pixels[t]) /
                               std::max(merged.pixels[t], 1e-3f)));
  EXPECT_LT(worst, 1e-4);
}

// Two mirror balls shot 90 degrees apart; the first has a "photographer"
// (garbage) at its centre, which its mask drops: the second ball covers those
// directions and the merge matches the probe.
TEST(Merge, MirrorBallsNinetyDegreesApartWithAMaskedPhotographer) {
  std::vector<Capture> captures;
  captures.push_back(cut(std::make_unique<MirrorBallMap>(256, 256)));
  captures.push_back(cut(std::make_unique<MirrorBallMap>(256, 256),
                         rotation_from_euler_degrees(90, 0, 0)));
  Image mask(256, 256, 1);
  for (int j = 0; j < 256; ++j)
    for (int i = 0; i < 256; ++i) {
      const bool photographer = std::hypot(i + 0.5 - 128, j + 0.5 - 128) < 40;
      mask.at(i, j, 0) = photographer ? 0.0f : 1.0f;
      if (photographer)
        for (int c = 0; c < 3; ++c)
          captures[0].map.image.at(i, j, c) = 1000.0f;
    }
  const LatLongMap ll(128, 64);
  const Image unmasked = merge_captures(captures, ll, kId);
  EXPECT_GT(merged_error(unmasked, ll), 0.1)
      << "the photographer must show without the mask";
  captures[0].mask = mask;
  MergeReport report;
  const Image merged = merge_captures(captures, ll, kId, &report);
  EXPECT_LT(merged_error(merged, ll), 0.05);
  EXPECT_LT(report.uncovered_solid_angle, 1e-3);
}

// Two 90-degree views (+Z and +X) leave 4 pi - 2 x 4 asin(1/2) = 8 pi / 3
// uncovered; what they see is the probe.
TEST(Merge, UncoveredSolidAngleOfTwoViews) {
  std::vector<Capture> captures;
  ViewParams v;
  v.fov_degrees = 90;
  captures.push_back(cut(std::make_unique<PerspectiveMap>(192, 192, v)));
  v.forward = Vec3(1, 0, 0);
  captures.push_back(cut(std::make_unique<PerspectiveMap>(192, 192, v)));
  const LatLongMap ll(256, 128);
  MergeReport report;
  const Image merged = merge_captures(captures, ll, kId, &report);
  EXPECT_NEAR(report.uncovered_solid_angle, 8 * kPi / 3, 0.01 * 8 * kPi / 3);
  EXPECT_LT(merged_error(merged, ll), 0.03);
  for (int j = 0; j < ll.height(); ++j)
    for (int i = 0; i < ll.width(); ++i)
      if (merged.at(i, j, 3) == 0.0f) {
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(merged.at(i, j, c), 0.0f);
      }
}

// envmerge on two fisheye files that envconvert wrote (their views come from
// metadata), one of them as a spec.
TEST(Merge, ToolMergesFilesAndReportsCoverage) {
  const fs::path dir = fs::temp_directory_path() /
                       ("envkit_test_merge_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  EnvMap ref;
  ref.param = std::make_unique<LatLongMap>(1024, 512);
  ref.image = reference();
  const std::string src = (dir / "ref.exr").string(),
                    front = (dir / "front.exr").string(),
                    back = (dir / "back.exr").string(),
                    out = (dir / "merged.exr").string();
  save_envmap(src, ref);
  auto r = test::run_tool("envconvert",
                          {src, "-o", front, "--to", "fisheye", "--lens",
                           "equisolid", "--fov", "200", "--size", "200", "-q"},
                          dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envconvert",
                     {src, "-o", back, "--to", "fisheye", "--lens", "equisolid",
                      "--fov", "200", "--view-dir", "180,0", "--size", "200",
                      "-q"},
                     dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envmerge",
                     {front, back, "-o", out, "--size", "64", "--json"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_LT(j["uncovered_sr"].get<double>(), 1e-3);
  EXPECT_EQ(j["captures"].size(), 2u);
  EXPECT_LT(merged_error(load_envmap(out).image, LatLongMap(128, 64)), 0.03);
  // Only the front: half the sphere and a bit is seen.
  r = test::run_tool(
      "envmerge",
      {front, "-o", (dir / "half.exr").string(), "--size", "64", "--json"},
      dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(nlohmann::json::parse(r.out)["uncovered_sr"].get<double>(),
              kTwoPi * (1 + std::cos(100 * kPi / 180)), 0.02);
  // A bad key is a usage error; no output.
  r = test::run_tool(
      "envmerge", {front + "@colour=3", "-o", (dir / "bad.exr").string()}, dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir / "bad.exr"));
  fs::remove_all(dir);
}
