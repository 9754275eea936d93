// Resampling where source and output texels coincide: the same grid is the identity for every map and filter, a
// permutation of whole texels (rotations by whole texels, convention and layout changes) moves texels unchanged,
// and same-size maps that nearly coincide are not supersampled (no blur beyond the footprint's).
#include <envkit/maps/angular.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/fisheye.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/maps/perspective.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "cli_support.h"

using namespace envkit;

namespace {

struct Named {
  std::string name;
  std::shared_ptr<Parameterization> p;
};

ViewParams tilted_view(double fov_degrees) {
  ViewParams v;
  v.forward = Vec3(0.3, 0.8, 0.52);  // the sun of distinct_map() is in view
  v.roll_degrees = 10.0;
  v.fov_degrees = fov_degrees;
  v.lens = Lens::Equisolid;
  return v;
}

std::vector<Named> every_grid() {
  return {
      {"latlong", std::make_shared<LatLongMap>(64, 32)},
      {"latlong-corner", std::make_shared<LatLongMap>(65, 33, TexelGrid::Corner)},
      {"cube-vstrip", std::make_shared<CubeMap>(12)},
      {"cube-hcross-gl", std::make_shared<CubeMap>(12, CubeLayout::HorizontalCross, CubeBasis::GL)},
      {"cube-corner", std::make_shared<CubeMap>(12, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner)},
      {"octahedral", std::make_shared<OctahedralMap>(30)},
      {"angular", std::make_shared<AngularMap>(34, 34)},
      {"mirrorball", std::make_shared<MirrorBallMap>(34, 34)},
      {"mirrorball-cropped", std::make_shared<MirrorBallMap>(40, 30, 20.0, 12.0, 17.0)},
      {"paraboloid", std::make_shared<DualParaboloidMap>(48, 24)},
      {"healpix", std::make_shared<HealpixMap>(8)},
      {"perspective", std::make_shared<PerspectiveMap>(40, 30, tilted_view(70.0))},
      {"fisheye", std::make_shared<FisheyeMap>(36, 36, tilted_view(200.0))}};
}

// Distinct values everywhere (so a misplaced texel shows) and one sun-like texel that the area filter splats.
Image distinct_map(const Parameterization& p) {
  Image img(p.width(), p.height(), 3);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec2 q;
      Vec3 d;
      if (!p.covered_point(i, j, q) || !p.to_direction(q, d)) continue;
      const float base = 1.0f + 0.001f * float(j * p.width() + i);
      img.at(i, j, 0) = base;
      img.at(i, j, 1) = base * float(1.5 + 0.5 * d.y);
      img.at(i, j, 2) = float(0.2 + 0.1 * d.x * d.x);
    }
  const Vec2 sun = p.to_image(Vec3(0.3, 0.8, 0.52));
  for (int c = 0; c < 3; ++c) img.at(int(sun.x), int(sun.y), c) = 1e6f;
  return img;
}

// Colour channels of every texel, exactly.
void expect_same_colours(const Image& got, const Image& want, const std::string& what) {
  ASSERT_EQ(got.width, want.width) << what;
  ASSERT_EQ(got.height, want.height) << what;
  int wrong = 0;
  for (int j = 0; j < want.height; ++j)
    for (int i = 0; i < want.width; ++i)
      for (int c = 0; c < 3; ++c)
        if (got.at(i, j, c) != want.at(i, j, c) && ++wrong <= 3)
          ADD_FAILURE() << what << ": texel (" << i << ", " << j << ") channel " << c << " is " << got.at(i, j, c)
                        << ", want " << want.at(i, j, c);
  EXPECT_EQ(wrong, 0) << what;
}

ResampleOptions with_filter(Filter f, AreaMethod m = AreaMethod::Auto) {
  ResampleOptions o;
  o.filter = f;
  o.area_method = m;
  return o;
}

struct FilterCase {
  std::string name;
  ResampleOptions options;
};

std::vector<FilterCase> every_filter() {
  return {{"nearest", with_filter(Filter::Nearest)},
          {"bilinear", with_filter(Filter::Bilinear)},
          {"bicubic", with_filter(Filter::Bicubic)},
          {"area", with_filter(Filter::Area)},
          {"area-gather", with_filter(Filter::Area, AreaMethod::Gather)}};
}

Mat3 yaw_degrees(double deg) { return rotation_from_euler_degrees(deg, 0.0, 0.0); }

}  // namespace

TEST(ResampleExact, SameGridIsTheIdentityForEveryMapAndFilter) {
  // The same map frame reached through a non-trivial rotation on both sides still composes to the identity.
  const Mat3 frame = rotation_from_euler_degrees(31.0, -12.0, 7.0);
  for (const Named& m : every_grid()) {
    const Image src = distinct_map(*m.p);
    for (const FilterCase& f : every_filter()) {
      const std::string what = m.name + " with " + f.name;
      expect_same_colours(resample({src, *m.p, identity3()}, *m.p, identity3(), f.options), src, what);
      const auto copy = m.p->clone();  // an equal grid, not the same object
      expect_same_colours(resample({src, *m.p, frame}, *copy, frame, f.options), src, what + ", rotated frames");
    }
  }
}

TEST(ResampleExact, SameGridKeepsCoverageOfDisks) {
  const MirrorBallMap ball(40, 30, 20.0, 12.0, 17.0);  // cropped by the image's top edge
  const Image src = distinct_map(ball);
  const Image out = resample({src, ball, identity3()}, ball, identity3());
  ASSERT_EQ(out.channels, 4);
  for (int j = 0; j < ball.height(); ++j)
    for (int i = 0; i < ball.width(); ++i)
      EXPECT_EQ(out.at(i, j, 3), ball.texel_solid_angle(i, j) > 0.0 ? 1.0f : 0.0f) << i << ", " << j;
}

TEST(ResampleExact, DifferentGridsAreNotCopied) {
  // Same kind and size but other layout parameters must resample, not copy.
  const std::vector<std::pair<std::shared_ptr<Parameterization>, std::shared_ptr<Parameterization>>> pairs = {
      {std::make_shared<LatLongMap>(64, 32), std::make_shared<LatLongMap>(64, 32, TexelGrid::Corner)},
      {std::make_shared<CubeMap>(12), std::make_shared<CubeMap>(12, CubeLayout::VerticalStrip, CubeBasis::GL)},
      {std::make_shared<MirrorBallMap>(34, 34), std::make_shared<MirrorBallMap>(34, 34, 17.0, 17.0, 16.0)},
      {std::make_shared<FisheyeMap>(36, 36, tilted_view(200.0)),
       std::make_shared<FisheyeMap>(36, 36, tilted_view(190.0))},
      {std::make_shared<PerspectiveMap>(40, 30, tilted_view(70.0)),
       std::make_shared<PerspectiveMap>(40, 30, tilted_view(60.0))}};
  for (const auto& [a, b] : pairs) {
    EXPECT_FALSE(a->same_grid(*b)) << a->describe() << " vs " << b->describe();
    EXPECT_TRUE(a->same_grid(*a->clone())) << a->describe();
  }
  EXPECT_FALSE(LatLongMap(64, 32).same_grid(OctahedralMap(32)));
}

TEST(ResampleExact, YawByWholeTexelsShiftsColumns) {
  const LatLongMap ll(64, 32);
  const Image src = distinct_map(ll);
  for (const int k : {1, 5, 16, 63}) {
    for (const FilterCase& f : every_filter()) {
      const Image out = resample({src, ll, yaw_degrees(360.0 * k / 64)}, ll, identity3(), f.options);
      // Column i of the output is some column (i + s) mod W of the source, the same s for every column and row.
      int shift = -1;
      for (int s = 0; s < 64 && shift < 0; ++s)
        if (out.at(0, 10, 0) == src.at(s, 10, 0)) shift = s;
      ASSERT_GE(shift, 0) << k << " texels with " << f.name;
      EXPECT_TRUE(shift == k || shift == 64 - k) << shift;
      Image want(64, 32, 3);
      for (int j = 0; j < 32; ++j)
        for (int i = 0; i < 64; ++i)
          for (int c = 0; c < 3; ++c) want.at(i, j, c) = src.at((i + shift) % 64, j, c);
      expect_same_colours(out, want, "yaw by " + std::to_string(k) + " texels with " + f.name);
    }
  }
}

TEST(ResampleExact, PermutationsOfWholeTexelsRoundTripExactly) {
  struct Case {
    std::string name;
    std::shared_ptr<Parameterization> a, b;
    Mat3 b_to_world;
  };
  const Mat3 blender = convention("blender").frame(Kind::LatLong);
  const std::vector<Case> cases = {
      {"cube vstrip -> hcross", std::make_shared<CubeMap>(12),
       std::make_shared<CubeMap>(12, CubeLayout::HorizontalCross), identity3()},
      {"cube envkit -> GL basis", std::make_shared<CubeMap>(12),
       std::make_shared<CubeMap>(12, CubeLayout::VerticalCross, CubeBasis::GL), identity3()},
      {"cube yaw 90", std::make_shared<CubeMap>(12), std::make_shared<CubeMap>(12), yaw_degrees(90.0)},
      {"cube pitch -90", std::make_shared<CubeMap>(12), std::make_shared<CubeMap>(12),
       rotation_from_euler_degrees(0.0, -90.0, 0.0)},
      {"latlong envkit -> blender frame", std::make_shared<LatLongMap>(64, 32), std::make_shared<LatLongMap>(64, 32),
       blender},
      {"octahedral yaw 90", std::make_shared<OctahedralMap>(30), std::make_shared<OctahedralMap>(30),
       yaw_degrees(90.0)}};
  for (const Case& c : cases) {
    const Image src = distinct_map(*c.a);
    const auto src_power = total_power(src, *c.a);
    for (const FilterCase& f : every_filter()) {
      const std::string what = c.name + " with " + f.name;
      const Image mid = resample({src, *c.a, identity3()}, *c.b, c.b_to_world, f.options);
      // Every output texel is one of the source's (a permutation), so power is kept to the summation's round-off.
      std::map<std::tuple<float, float, float>, int> values;
      for (int j = 0; j < src.height; ++j)
        for (int i = 0; i < src.width; ++i)
          if (c.a->texel_solid_angle(i, j) > 0.0) ++values[{src.at(i, j, 0), src.at(i, j, 1), src.at(i, j, 2)}];
      int foreign = 0;
      for (int j = 0; j < mid.height; ++j)
        for (int i = 0; i < mid.width; ++i)
          if (c.b->texel_solid_angle(i, j) > 0.0 && !values.count({mid.at(i, j, 0), mid.at(i, j, 1), mid.at(i, j, 2)}))
            ++foreign;
      EXPECT_EQ(foreign, 0) << what;
      const auto mid_power = total_power(mid, *c.b);
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(mid_power[ch], src_power[ch], 1e-12 * src_power[ch]) << what << " channel " << ch;
      const Image back = resample({mid, *c.b, c.b_to_world}, *c.a, identity3(), f.options);
      expect_same_colours(back, src, what + " and back");
    }
  }
}

TEST(ResampleExact, NearlyCoincidentSameSizeMapsAreNotSupersampled) {
  // A same-size lat-long turned by far less than a texel: output texels are the size and shape of the source's,
  // including the long thin rows at the poles, so the area filter is the bilinear reconstruction at each centre.
  // Supersampling them (as when comparing a row's width with the square root of its solid angle) adds blur.
  const LatLongMap ll(128, 64);
  Image src(128, 64, 3);
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 128; ++i)
      for (int c = 0; c < 3; ++c) src.at(i, j, c) = ((i + j + c) % 2) ? 2.0f : 0.5f;  // texel-scale checker
  const Mat3 tiny = rotation_from_euler_degrees(0.0, 1e-3, 0.0);
  const Image area = resample({src, ll, tiny}, ll, identity3(), with_filter(Filter::Area, AreaMethod::Gather));
  const Image bilinear = resample({src, ll, tiny}, ll, identity3(), with_filter(Filter::Bilinear));
  double worst = 0.0;
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 128; ++i)
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs(double(area.at(i, j, c)) - bilinear.at(i, j, c)) / bilinear.at(i, j, c));
  EXPECT_LT(worst, 1e-5);
  // And the turn is small enough that both stay within a hair of the source (no texel loses its checker value).
  double drift = 0.0;
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 128; ++i) drift = std::max(drift, std::abs(double(area.at(i, j, 0)) - src.at(i, j, 0)));
  EXPECT_LT(drift, 0.05);
}

namespace {

class ResampleExactCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("envkit_resample_exact_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  test::CommandResult run(const std::string& tool, const std::vector<std::string>& args) const {
    return test::run_tool(tool, args, dir_);
  }
  std::filesystem::path dir_;
};

}  // namespace

TEST_F(ResampleExactCli, EnvdiffOfAFileWithItselfIsExactlyZero) {
  const std::vector<std::vector<std::string>> probes = {
      {"default", "--size", "256x128"},
      {"default", "--size", "128x64", "--convention", "openexr"},
      {"default", "--param", "cube", "--size", "24", "--convention", "openexr"},
      {"default", "--param", "mirrorball", "--size", "64"}};
  int k = 0;
  for (std::vector<std::string> args : probes) {
    const std::string file = path("p" + std::to_string(k++) + ".exr");
    args.insert(args.begin() + 1, {"-o", file});
    ASSERT_EQ(run("envprobe", args).code, 0);
    for (const std::string filter : {"area", "bilinear"}) {
      const auto r = run("envdiff", {file, file, "--filter", filter, "--json", "--fail-above", "0"});
      ASSERT_EQ(r.code, 0) << args[0] << " " << filter << ": " << r.err;
      const auto j = nlohmann::json::parse(r.out);
      EXPECT_EQ(j.at("relmse").get<double>(), 0.0) << file << " " << filter;
      EXPECT_EQ(j.at("rmse").get<double>(), 0.0) << file << " " << filter;
    }
  }
}

TEST_F(ResampleExactCli, ConvertingToTheSameGridLeavesEveryTexel) {
  ASSERT_EQ(run("envprobe", {"default", "-o", path("sky.exr"), "--size", "256x128"}).code, 0);
  ASSERT_EQ(run("envconvert", {path("sky.exr"), "-o", path("same.exr"), "--to", "latlong"}).code, 0);
  ASSERT_EQ(run("envconvert", {path("sky.exr"), "-o", path("cube.exr"), "--to", "cube", "--size", "32"}).code, 0);
  ASSERT_EQ(run("envconvert", {path("cube.exr"), "-o", path("gl_%.exr"), "--to", "cube", "--convention", "gl"}).code,
            0);
  ASSERT_EQ(
      run("envconvert", {path("gl_%.exr"), "-o", path("back.exr"), "--to", "cube", "--convention", "envkit"}).code, 0);
  for (const auto& [a, b] : {std::pair{"sky.exr", "same.exr"}, std::pair{"cube.exr", "back.exr"}}) {
    const auto r = run("envdiff", {path(a), path(b), "--json", "--filter", "nearest"});
    ASSERT_EQ(r.code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("relmse").get<double>(), 0.0) << a << " vs " << b;
    EXPECT_EQ(j.at("max_abs_error").at("value").get<double>(), 0.0) << a << " vs " << b;
  }
}
