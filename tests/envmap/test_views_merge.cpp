// Merging captures (merge.h, envmerge): captures cut from the built-in analytic
// outdoor probe (fisheyes, mirror balls 90 degrees apart, perspective views)
// merge back into the probe's lat-long; masks drop a "photographer", exposures
// undo darker shots, and the uncovered solid angle matches the closed form.
#include <envkit/envmap/envmap.h>
#include <envkit/envmap/merge.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/fisheye.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/perspective.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/probes.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_support.h"

namespace fs = std::filesystem;
using namespace envkit;

namespace {

const Mat3 kId = identity3();

// The default probe on a fine lat-long, the source every capture is cut from.
const Image& reference() {
  static const Image ref = probes::rasterize(*probes::make_default_probe(), LatLongMap(1024, 512));
  return ref;
}

Capture cut(std::unique_ptr<Parameterization> param, const Mat3& rotation = kId, double scale = 1.0) {
  const LatLongMap ll(1024, 512);
  Capture c;
  c.map.param = std::move(param);
  c.map.rotation = rotation;
  c.map.image = resample({reference(), ll, kId}, *c.map.param, c.map.to_world());
  for (float& v : c.map.image.pixels) v = float(v * scale);
  if (c.map.image.alpha_channel >= 0)  // coverage is not light: keep it
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
double merged_error(const Image& merged, const LatLongMap& ll) {
  const Image ref = resample({reference(), LatLongMap(1024, 512), kId}, ll, kId);
  const SolidAngleTable omega(ll);
  const probes::OutdoorProbe probe;
  double num = 0, den = 0;
  for (int j = 0; j < ll.height(); ++j)
    for (int i = 0; i < ll.width(); ++i) {
      if (merged.at(i, j, 3) < 0.999f) continue;
      Vec3 d;
      ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
      if (angle_between(d, probe.sun_direction()) < 3 * kPi / 180) continue;
      for (int c = 0; c < 3; ++c) {
        const double e = merged.at(i, j, c) - ref.at(i, j, c);
        num += omega(i, j) * e * e;
        den += omega(i, j) * double(ref.at(i, j, c)) * ref.at(i, j, c);
      }
    }
  return std::sqrt(num / den);
}

}  // namespace

// Two 200-degree equisolid fisheyes back to back see everything; merged they
// give the probe back.
TEST(Merge, TwoFisheyesBackToBackGiveTheProbe) {
  std::vector<Capture> captures;
  captures.push_back(cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(0, 200))));
  captures.push_back(cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(180, 200))));
  const LatLongMap ll(128, 64);
  MergeReport report;
  const Image merged = merge_captures(captures, ll, kId, &report);
  EXPECT_LT(report.uncovered_solid_angle, 1e-3);
  EXPECT_LT(merged_error(merged, ll), 0.02);
  ASSERT_EQ(report.weight_share.size(), 2u);
  EXPECT_NEAR(report.weight_share[0], 0.5, 0.05);
  // Each sees its 200-degree cap: 2 pi (1 - cos 100 deg).
  for (double s : report.covered_solid_angle) EXPECT_NEAR(s, kTwoPi * (1 - std::cos(100 * kPi / 180)), 0.02 * s);
  // A back shot one stop and a half darker (x 0.35), merged with exposure 1 /
  // 0.35, gives the same map.
  std::vector<Capture> dark;
  dark.push_back(cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(0, 200))));
  dark.push_back(cut(std::make_unique<FisheyeMap>(320, 320, fisheye_view(180, 200)), kId, 0.35));
  dark[1].exposure = 1 / 0.35;
  const Image again = merge_captures(dark, ll, kId);
  double worst = 0;
  for (std::size_t t = 0; t < again.pixels.size(); ++t)
    worst = std::max(worst, double(std::abs(again.pixels[t] - merged.pixels[t]) / std::max(merged.pixels[t], 1e-3f)));
  EXPECT_LT(worst, 1e-4);
}

// Two mirror balls shot 90 degrees apart; the first has a "photographer"
// (garbage) at its centre, which its mask drops: the second ball covers those
// directions and the merge matches the probe.
TEST(Merge, MirrorBallsNinetyDegreesApartWithAMaskedPhotographer) {
  std::vector<Capture> captures;
  captures.push_back(cut(std::make_unique<MirrorBallMap>(256, 256)));
  captures.push_back(cut(std::make_unique<MirrorBallMap>(256, 256), rotation_from_euler_degrees(90, 0, 0)));
  Image mask(256, 256, 1);
  for (int j = 0; j < 256; ++j)
    for (int i = 0; i < 256; ++i) {
      const bool photographer = std::hypot(i + 0.5 - 128, j + 0.5 - 128) < 40;
      mask.at(i, j, 0) = photographer ? 0.0f : 1.0f;
      if (photographer)
        for (int c = 0; c < 3; ++c) captures[0].map.image.at(i, j, c) = 1000.0f;
    }
  const LatLongMap ll(128, 64);
  const Image unmasked = merge_captures(captures, ll, kId);
  EXPECT_GT(merged_error(unmasked, ll), 0.1) << "the photographer must show without the mask";
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
        for (int c = 0; c < 3; ++c) ASSERT_EQ(merged.at(i, j, c), 0.0f);
      }
}

// envmerge on two fisheye files that envconvert wrote (their views come from
// metadata), one of them as a spec.
TEST(Merge, ToolMergesFilesAndReportsCoverage) {
  const fs::path dir = fs::temp_directory_path() / ("envkit_test_merge_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  EnvMap ref;
  ref.param = std::make_unique<LatLongMap>(1024, 512);
  ref.image = reference();
  const std::string src = (dir / "ref.exr").string(), front = (dir / "front.exr").string(),
                    back = (dir / "back.exr").string(), out = (dir / "merged.exr").string();
  save_envmap(src, ref);
  auto r = test::run_tool(
      "envconvert", {src, "-o", front, "--to", "fisheye", "--lens", "equisolid", "--fov", "200", "--size", "200", "-q"},
      dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envconvert",
                     {src, "-o", back, "--to", "fisheye", "--lens", "equisolid", "--fov", "200", "--view-dir", "180,0",
                      "--size", "200", "-q"},
                     dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envmerge", {front, back, "-o", out, "--size", "64", "--json"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_LT(j["uncovered_sr"].get<double>(), 1e-3);
  EXPECT_EQ(j["captures"].size(), 2u);
  EXPECT_LT(merged_error(load_envmap(out).image, LatLongMap(128, 64)), 0.03);
  // Only the front: half the sphere and a bit is seen.
  r = test::run_tool("envmerge", {front, "-o", (dir / "half.exr").string(), "--size", "64", "--json"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(nlohmann::json::parse(r.out)["uncovered_sr"].get<double>(), kTwoPi * (1 + std::cos(100 * kPi / 180)),
              0.02);
  // A bad key is a usage error; no output.
  r = test::run_tool("envmerge", {front + "@colour=3", "-o", (dir / "bad.exr").string()}, dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(dir / "bad.exr"));
  fs::remove_all(dir);
}

namespace {

// The probe's lat-long (with its sun) as a capture that covers the sphere.
Capture whole_probe() {
  Capture c;
  c.map.param = std::make_unique<LatLongMap>(1024, 512);
  c.map.image = reference();
  c.name = "probe";
  return c;
}

// Fraction of texel (i, j)'s solid angle that `sees` holds on, by brute force:
// n x n sub-cells weighted by their exact solid angles.
template <class Sees>
double brute_force_coverage(const Parameterization& p, int i, int j, int n, const Sees& sees) {
  double in = 0, all = 0;
  for (int b = 0; b < n; ++b)
    for (int a = 0; a < n; ++a) {
      const double x0 = i + double(a) / n, y0 = j + double(b) / n;
      const double w = p.solid_angle(x0, y0, x0 + 1.0 / n, y0 + 1.0 / n);
      Vec3 d;
      if (!(w > 0) || !p.to_direction(Vec2(x0 + 0.5 / n, y0 + 0.5 / n), d)) continue;
      all += w;
      if (sees(d)) in += w;
    }
  return all > 0 ? in / all : 0.0;
}

}  // namespace

// A map that covers the sphere merges to itself: alpha exactly 1 wherever the
// output holds data, and the radiance the area resampler gives (sun included),
// whatever the output's kind and size.
TEST(Merge, ACompleteMapMergesToItself) {
  const std::vector<Capture> captures = [] {
    std::vector<Capture> v;
    v.push_back(whole_probe());
    return v;
  }();
  const LatLongMap ll64(128, 64), ll8(16, 8);
  const CubeMap cube(24);
  const OctahedralMap octa(48);
  const MirrorBallMap ball(64, 64);
  for (const Parameterization* dst : std::initializer_list<const Parameterization*>{&ll64, &ll8, &cube, &octa, &ball}) {
    SCOPED_TRACE(dst->describe());
    const Image merged = merge_captures(captures, *dst, kId);
    const Image ref = resample({reference(), LatLongMap(1024, 512), kId}, *dst, kId);
    const SolidAngleTable omega(*dst);
    int wrong_alpha = 0, wrong_colour = 0;
    for (int j = 0; j < dst->height(); ++j)
      for (int i = 0; i < dst->width(); ++i) {
        if (!(omega(i, j) > 0)) {
          wrong_alpha += merged.at(i, j, 3) != 0.0f;
          continue;
        }
        wrong_alpha += merged.at(i, j, 3) != 1.0f;
        for (int c = 0; c < 3; ++c)
          wrong_colour += std::abs(merged.at(i, j, c) - ref.at(i, j, c)) > 2e-7f * std::abs(ref.at(i, j, c));
      }
    EXPECT_EQ(wrong_alpha, 0);
    EXPECT_EQ(wrong_colour, 0);
  }
  // The same through the tools: envmerge of a complete map is envconvert's
  // map of the same size.
  const fs::path dir = fs::temp_directory_path() / ("envkit_test_merge_self_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  EnvMap ref;
  ref.param = std::make_unique<LatLongMap>(1024, 512);
  ref.image = reference();
  const std::string src = (dir / "sky.exr").string(), merged = (dir / "m.exr").string(),
                    converted = (dir / "c.exr").string();
  save_envmap(src, ref);
  auto r = test::run_tool("envmerge", {src, "-o", merged, "--size", "64", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envconvert", {src, "-o", converted, "--to", "latlong", "--size", "64", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const Image m = load_envmap(merged).image, c = load_envmap(converted).image;
  ASSERT_EQ(m.width, c.width);
  ASSERT_EQ(m.height, c.height);
  double worst = 0, alpha = 1;
  for (int j = 0; j < m.height; ++j)
    for (int i = 0; i < m.width; ++i) {
      alpha = std::min(alpha, double(m.at(i, j, 3)));
      for (int k = 0; k < 3; ++k)
        worst =
            std::max(worst, std::abs(double(m.at(i, j, k)) - c.at(i, j, k)) / std::max(1e-6, double(c.at(i, j, k))));
    }
  EXPECT_EQ(alpha, 1.0);
  EXPECT_LT(worst, 1e-6);
  fs::remove_all(dir);
}

// Two views whose union is the sphere merge to alpha 1 everywhere, also on the
// texels each of them covers only in part: 180-degree fisheyes back to back
// (their common edge cuts through texels), and 200-degree ones that overlap.
TEST(Merge, HalfCapturesThatCoverTheSphereTogetherGiveAlphaOne) {
  for (const double fov : {180.0, 200.0}) {
    SCOPED_TRACE(fov);
    std::vector<Capture> captures;
    ViewParams front = fisheye_view(10, fov), back = fisheye_view(190, fov);
    front.lens = back.lens = Lens::Equidistant;
    captures.push_back(cut(std::make_unique<FisheyeMap>(256, 256, front)));
    captures.push_back(cut(std::make_unique<FisheyeMap>(256, 256, back)));
    const LatLongMap ll(128, 64);
    MergeReport report;
    const Image merged = merge_captures(captures, ll, kId, &report);
    int below = 0;
    for (int j = 0; j < ll.height(); ++j)
      for (int i = 0; i < ll.width(); ++i) below += merged.at(i, j, 3) != 1.0f;
    EXPECT_EQ(below, 0);
    EXPECT_EQ(report.uncovered_solid_angle, 0.0);
  }
}

// A partial capture's alpha is the covered fraction of each texel's solid
// angle: a 120-degree fisheye looking straight up covers the cap within 60
// degrees of +Y, so on the lat-long row the cap's edge cuts through the
// fraction is (cos theta0 - cos 60) / (cos theta0 - cos theta1) exactly.
TEST(Merge, CoverageOfACapIsItsExactFraction) {
  ViewParams up;
  up.forward = direction_from_yaw_pitch(0, 90);
  up.fov_degrees = 120;
  up.lens = Lens::Equidistant;
  std::vector<Capture> captures;
  captures.push_back(cut(std::make_unique<FisheyeMap>(200, 200, up)));
  const LatLongMap ll(128, 64);
  MergeReport report;
  const Image merged = merge_captures(captures, ll, kId, &report);
  const double edge = std::cos(kPi / 3);
  double worst = 0;
  for (int j = 0; j < ll.height(); ++j) {
    const double c0 = std::cos(kPi * j / ll.height()), c1 = std::cos(kPi * (j + 1) / ll.height());
    const double expected = std::clamp((c0 - std::max(c1, edge)) / (c0 - c1), 0.0, 1.0);
    for (int i = 0; i < ll.width(); ++i) {
      if (expected == 1.0 || expected == 0.0) {
        ASSERT_EQ(merged.at(i, j, 3), float(expected)) << i << "," << j;
      }
      worst = std::max(worst, std::abs(merged.at(i, j, 3) - expected));
    }
  }
  EXPECT_LT(worst, 1e-3);
  // The cap's solid angle: 2 pi (1 - cos 60) = pi.
  EXPECT_NEAR(report.covered_solid_angle[0], kPi, 1e-4 * kPi);
  EXPECT_NEAR(report.uncovered_solid_angle, 3 * kPi, 1e-4 * kPi);
}

// The same for a tilted, rolled perspective view (a spherical quadrilateral
// with corners) onto a lat-long and a cube, against a brute-force reference.
TEST(Merge, CoverageOfAViewIsItsExactFraction) {
  ViewParams v;
  v.forward = direction_from_yaw_pitch(20, 15);
  v.fov_degrees = 60;
  v.roll_degrees = 10;
  std::vector<Capture> captures;
  captures.push_back(cut(std::make_unique<PerspectiveMap>(120, 90, v)));
  const Parameterization& view = *captures[0].map.param;
  const auto sees = [&](const Vec3& d) {
    const Vec2 p = view.to_image(d);
    return p.x >= 0 && p.y >= 0 && p.x <= view.width() && p.y <= view.height();
  };
  const LatLongMap ll(64, 32);
  const CubeMap cube(12);
  for (const Parameterization* dst : std::initializer_list<const Parameterization*>{&ll, &cube}) {
    SCOPED_TRACE(dst->describe());
    const Image merged = merge_captures(captures, *dst, kId);
    double worst = 0;
    int straddling = 0;
    for (int j = 0; j < dst->height(); ++j)
      for (int i = 0; i < dst->width(); ++i) {
        const double coarse = brute_force_coverage(*dst, i, j, 16, sees);
        const float a = merged.at(i, j, 3);
        const bool uniform = coarse == 0.0 || coarse == 1.0;
        if (uniform && a == float(coarse)) continue;
        straddling += !uniform;
        const double fine = brute_force_coverage(*dst, i, j, 256, sees);
        worst = std::max(worst, std::abs(a - fine));
      }
    EXPECT_GT(straddling, 10);
    EXPECT_LT(worst, 1e-3);
  }
}
