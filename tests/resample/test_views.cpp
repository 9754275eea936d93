// Perspective and fisheye views (perspective.h, fisheye.h, view.h): known
// directions on known pixels, round trips, solid angles against the views'
// closed forms, a 90-degree view cropped from a map against the matching cube
// face, no aliasing when cropping from an 8k map, embedding with coverage
// alpha, and the tools re-reading views.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/fisheye.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/perspective.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "cli_support.h"

namespace fs = std::filesystem;
using namespace envkit;

namespace {

const Mat3 kId = identity3();

Vec3 smooth_env(const Vec3& d) {
  return Vec3(1.0 + 0.5 * d.x + 0.3 * d.y * d.y, 0.8 + 0.4 * std::sin(2.0 * d.z) + 0.2 * d.y,
              0.6 + 0.3 * d.x * d.z + 0.25 * d.y);
}

Image rasterize(const Parameterization& p, Vec3 (*f)(const Vec3&)) {
  Image img(p.width(), p.height(), 3);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec3 d;
      if (!p.to_direction(Vec2(i + 0.5, j + 0.5), d)) continue;
      const Vec3 v = f(d);
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = float(v[c]);
    }
  return img;
}

ViewParams view(Vec3 forward, double fov, double roll = 0.0, Lens lens = Lens::Equidistant) {
  ViewParams v;
  v.forward = forward;
  v.fov_degrees = fov;
  v.roll_degrees = roll;
  v.lens = lens;
  return v;
}

const Lens kLenses[] = {Lens::Equidistant, Lens::Equisolid, Lens::Orthographic, Lens::Stereographic};

}  // namespace

// Known directions: looking along +Z with +Y up, image right is -X (vec.h); the
// right edge's middle of a 90-degree view sees 45 degrees to the right; a
// camera rolled counter-clockwise by 90 has its up where its left was (+X).
TEST(Views, PerspectiveSeesKnownDirections) {
  const PerspectiveMap p(200, 100, view(Vec3(0, 0, 1), 90));
  Vec3 d;
  ASSERT_TRUE(p.to_direction(Vec2(100, 50), d));
  EXPECT_LT(angle_between(d, Vec3(0, 0, 1)), 1e-12);
  ASSERT_TRUE(p.to_direction(Vec2(200, 50), d));
  EXPECT_LT(angle_between(d, Vec3(-1, 0, 1).normalized()), 1e-12);
  // Vertical: square pixels, t_y = t_x / 2.
  ASSERT_TRUE(p.to_direction(Vec2(100, 0), d));
  EXPECT_LT(angle_between(d, Vec3(0, 0.5, 1).normalized()), 1e-12);
  EXPECT_NEAR(p.tan_half_y(), 0.5, 1e-15);
  // Behind the camera: outside the image.
  const Vec2 behind = p.to_image(Vec3(0.1, 0, -1));
  EXPECT_TRUE(behind.x < 0 || behind.y < 0);
  const PerspectiveMap rolled(100, 100, view(Vec3(0, 0, 1), 90, 90));
  ASSERT_TRUE(rolled.to_direction(Vec2(50, 0), d));
  EXPECT_LT(angle_between(d, Vec3(1, 0, 1).normalized()), 1e-12);
  // --fov-axis v: the fov spans the height.
  ViewParams vv = view(Vec3(1, 0, 0), 60);
  vv.fov_axis = FovAxis::Vertical;
  const PerspectiveMap vert(300, 100, vv);
  EXPECT_NEAR(vert.tan_half_y(), std::tan(kPi / 6), 1e-15);
  EXPECT_NEAR(vert.tan_half_x(), 3 * std::tan(kPi / 6), 1e-14);
  EXPECT_THROW(PerspectiveMap(10, 10, view(Vec3(0, 0, 1), 180)), Error);
}

TEST(Views, FisheyeLensesPlaceKnownAnglesAtTheirRadii) {
  const double theta = kPi / 6,
               h = kPi / 2;  // 30 degrees off axis, 180-degree lens
  const double expected[] = {theta / h, std::sin(theta / 2) / std::sin(h / 2), std::sin(theta) / std::sin(h),
                             std::tan(theta / 2) / std::tan(h / 2)};
  for (int k = 0; k < 4; ++k) {
    const FisheyeMap f(400, 400, view(Vec3(0, 0, 1), 180, 0, kLenses[k]));
    // 30 degrees to the right of +Z is towards -X.
    const Vec2 p = f.to_image(Vec3(-std::sin(theta), 0, std::cos(theta)));
    EXPECT_NEAR(p.x, 200 + 200 * expected[k], 1e-9) << lens_name(kLenses[k]);
    EXPECT_NEAR(p.y, 200, 1e-9) << lens_name(kLenses[k]);
    // Beyond the field of view: outside the image.
    const Vec2 q = f.to_image(Vec3(0, 0.1, -1));
    EXPECT_TRUE(q.x < 0 || q.y < 0) << lens_name(kLenses[k]);
  }
  // A 360-degree equidistant lens sees straight behind at its rim.
  const FisheyeMap full(100, 100, view(Vec3(0, 0, 1), 360));
  EXPECT_TRUE(full.covers_sphere());
  Vec3 d;
  ASSERT_TRUE(full.to_direction(Vec2(99.999999, 50), d));
  EXPECT_LT(angle_between(d, Vec3(0, 0, -1)), 1e-6);
  EXPECT_THROW(FisheyeMap(10, 10, view(Vec3(0, 0, 1), 200, 0, Lens::Orthographic)), Error);
  EXPECT_THROW(FisheyeMap(10, 10, view(Vec3(0, 0, 1), 360, 0, Lens::Stereographic)), Error);
}

TEST(Views, RoundTripsWithin1e6Radians) {
  std::vector<std::unique_ptr<Parameterization>> views;
  views.push_back(std::make_unique<PerspectiveMap>(320, 200, view(Vec3(0.3, 0.5, -1), 100, 17)));
  views.push_back(std::make_unique<PerspectiveMap>(320, 200, view(Vec3(0.3, 0.5, -1), 100, 17, Lens::Orthographic)));
  ViewParams hv = view(Vec3(-1, 0.2, 0.4), 80, 5);
  hv.fov_v_degrees = 30;
  views.push_back(std::make_unique<PerspectiveMap>(200, 200, hv));
  for (Lens l : kLenses)
    views.push_back(
        std::make_unique<FisheyeMap>(256, 256, view(Vec3(1, -0.2, 0.1), l == Lens::Orthographic ? 180 : 270, -30, l)));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const auto& v : views) {
    double worst = 0.0;
    int checked = 0;
    for (int k = 0; k < 20000; ++k) {
      const Vec2 p(u(rng) * v->width(), u(rng) * v->height());
      Vec3 d, back;
      if (!v->to_direction(p, d)) continue;
      const Vec2 q = v->to_image(d);
      ASSERT_TRUE(v->to_direction(q, back)) << v->describe();
      worst = std::max(worst, angle_between(d, back));
      ++checked;
    }
    EXPECT_GT(checked, 10000);
    EXPECT_LT(worst, 1e-6) << v->describe();
  }
}

// Solid angles of all texels sum to the view's closed form: 4 asin(sin(hfov/2)
// sin(vfov/2)) for a pinhole, 2 pi (1 - cos(fov/2)) for a fisheye's image
// circle.
TEST(Views, SolidAnglesSumToTheViewsClosedForms) {
  const PerspectiveMap p(160, 90, view(Vec3(0, 1, 1), 120));
  const double a = std::atan(p.tan_half_x()), b = std::atan(p.tan_half_y());
  EXPECT_NEAR(SolidAngleTable(p).total(), 4 * std::asin(std::sin(a) * std::sin(b)), 1e-6 * p.view_solid_angle());
  for (Lens l : kLenses)
    for (double fov : {90.0, 180.0, 300.0}) {
      if ((l == Lens::Orthographic && fov > 180) || (l == Lens::Stereographic && fov >= 360)) continue;
      const FisheyeMap f(120, 100, view(Vec3(0, 0, 1), fov, 0, l));
      const double expected = kTwoPi * (1 - std::cos(fov * kPi / 360));
      EXPECT_NEAR(SolidAngleTable(f).total(), expected, 1e-6 * expected) << f.describe();
    }
}

// The planar orthographic view: texel solid angles (perspective.h's closed form) against the midpoint rule on the
// density 1 / sqrt(1 - a^2 - b^2) over 256 x 256 sub-texels (away from the rim, where it is smooth), plane extents
// sin(fov / 2), and a view whose corners leave the hemisphere refused. A vertical field of view of its own sets the
// height's extent whatever the image's aspect, and survives the metadata round trip.
TEST(Views, OrthographicAndTwoFieldOfViewPerspectives) {
  const PerspectiveMap o(40, 30, view(Vec3(0.2, 1, 0.3), 100, 10, Lens::Orthographic));
  EXPECT_NEAR(o.tan_half_x(), std::sin(50 * kPi / 180), 1e-15);
  EXPECT_NEAR(SolidAngleTable(o).total(), o.view_solid_angle(), 1e-6 * o.view_solid_angle());
  for (const auto& [i, j] : {std::pair{0, 0}, std::pair{20, 15}, std::pair{39, 3}}) {
    double sum = 0.0;
    const int n = 256;
    for (int sj = 0; sj < n; ++sj)
      for (int si = 0; si < n; ++si)
        sum += o.solid_angle_density(Vec2(i + (si + 0.5) / n, j + (sj + 0.5) / n)) / (n * n);
    EXPECT_NEAR(o.texel_solid_angle(i, j), sum, 1e-6 * sum) << i << "," << j;
  }
  EXPECT_THROW(PerspectiveMap(16, 16, view(Vec3(0, 0, 1), 120, 0, Lens::Orthographic)), Error);
  EXPECT_NO_THROW(PerspectiveMap(16, 16, view(Vec3(0, 0, 1), 90, 0, Lens::Orthographic)));  // corners on the rim

  ViewParams hv = view(Vec3(0, 0, 1), 90);
  hv.fov_v_degrees = 40;
  const PerspectiveMap p(100, 100, hv);
  EXPECT_NEAR(p.tan_half_y(), std::tan(20 * kPi / 180), 1e-15);
  EXPECT_EQ(parse_view(format_view(hv)), hv);
  hv.fov_v_degrees = 180;
  EXPECT_THROW(PerspectiveMap(16, 16, hv), Error);
}

// A 90-degree view along a cube face's axis is that face: cropping it from a
// map with the area filter gives the face's values within test_resample's
// bounds (0.6% relative RMS; here per texel 0.5%).
TEST(Views, NinetyDegreeViewEqualsTheMatchingCubeFace) {
  const LatLongMap ll(512, 256);
  const Image src = rasterize(ll, smooth_env);
  const int n = 48;
  const CubeMap cube(n);
  const Image faces = resample({src, ll, kId}, cube, kId);
  // Envkit cube faces +X, +Z, -Z have right = forward x (+Y) and down = -Y: the
  // default view basis.
  for (int face : {0, 4, 5}) {
    const CubeFace& cf = cube.face(face);
    const PerspectiveMap v(n, n, view(cf.axis, 90));
    const Image crop = resample({src, ll, kId}, v, kId);
    ASSERT_EQ(crop.channels, 3) << "a view cropped from a whole map is covered everywhere";
    double worst = 0.0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
          const double f = faces.at(cf.origin_x + i, cf.origin_y + j, c);
          worst = std::max(worst, std::abs(crop.at(i, j, c) - f) / f);
        }
      }
    EXPECT_LT(worst, 5e-3) << "face " << face;
  }
}

// The narrowest views accepted see the radiance around the direction they look at: every texel between the
// smallest and largest of the four source texels nearest to it, and the same values as a view 1000 times wider
// (both far below one source texel); narrower views are refused rather than written black.
TEST(Views, NarrowestViewsSeeTheirDirectionAndNarrowerAreRefused) {
  const LatLongMap ll(64, 32);
  const Image src = rasterize(ll, smooth_env);
  const Vec3 forward = Vec3(0.3, 0.2, 1.0).normalized();
  const Vec2 at = ll.to_image(forward);
  const auto crop_of = [&](double fov, int lens) {
    const std::unique_ptr<Parameterization> v =
        lens < 0 ? std::unique_ptr<Parameterization>(std::make_unique<PerspectiveMap>(16, 16, view(forward, fov)))
                 : std::make_unique<FisheyeMap>(16, 16, view(forward, fov, 0.0, kLenses[lens]));
    return resample({src, ll, kId}, *v, kId);
  };
  const int x0 = int(std::floor(at.x - 0.5)), y0 = int(std::floor(at.y - 0.5));
  for (int lens = -1; lens < 4; ++lens) {
    const Image narrowest = crop_of(kMinFovDegrees, lens), wider = crop_of(1e-3, lens);
    for (int c = 0; c < 3; ++c) {
      float lo = src.at(x0, y0, c), hi = lo;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          lo = std::min(lo, src.at(x0 + dx, y0 + dy, c));
          hi = std::max(hi, src.at(x0 + dx, y0 + dy, c));
        }
      for (const int i : {6, 8, 9}) {  // inside every lens's image circle
        EXPECT_GE(narrowest.at(i, i, c), lo * (1 - 1e-6)) << "lens " << lens << " channel " << c;
        EXPECT_LE(narrowest.at(i, i, c), hi * (1 + 1e-6)) << "lens " << lens << " channel " << c;
        EXPECT_NEAR(narrowest.at(i, i, c), wider.at(8, 8, c), 1e-3 * hi) << "lens " << lens << " channel " << c;
      }
    }
  }
  for (const double fov : {0.0, 1e-20, 0.5 * kMinFovDegrees, std::nan("")}) {
    EXPECT_THROW(PerspectiveMap(16, 16, view(forward, fov)), Error) << fov;
    for (const Lens lens : kLenses) EXPECT_THROW(FisheyeMap(16, 16, view(forward, fov, 0.0, lens)), Error) << fov;
  }
}

// A checkerboard of one-texel squares on an 8192 x 4096 lat-long averages 0.5
// over any view texel: the area filter gives about that, nearest sampling
// aliases to values near 0 or 1.
TEST(Views, CropFromAn8kMapDoesNotAlias) {
  const LatLongMap ll(8192, 4096);
  Image src(8192, 4096, 1);
  for (int j = 0; j < 4096; ++j)
    for (int i = 0; i < 8192; ++i) src.at(i, j, 0) = float((i + j) & 1);
  const PerspectiveMap v(48, 32, view(Vec3(0.2, 0.3, 1), 60, 10));
  const Image area = resample({src, ll, kId}, v, kId);
  ResampleOptions nearest;
  nearest.filter = Filter::Nearest;
  const Image point = resample({src, ll, kId}, v, kId, nearest);
  double worst_area = 0.0, mean_point_dev = 0.0;
  for (int j = 0; j < v.height(); ++j)
    for (int i = 0; i < v.width(); ++i) {
      worst_area = std::max(worst_area, std::abs(area.at(i, j, 0) - 0.5));
      mean_point_dev += std::abs(point.at(i, j, 0) - 0.5) / (v.width() * v.height());
    }
  EXPECT_LT(worst_area, 0.05);
  EXPECT_GT(mean_point_dev,
            0.4);  // the comparison can fail: point sampling does alias here
}

// Embedding a view into a lat-long: alpha is the covered fraction, its
// solid-angle integral is the view's solid angle, colour is 0 where alpha is 0,
// and a view's flux arrives in the map.
TEST(Views, EmbeddingAViewGivesCoverageAlpha) {
  for (int k = 0; k < 2; ++k) {
    std::unique_ptr<Parameterization> v;
    if (k == 0)
      v = std::make_unique<PerspectiveMap>(96, 64, view(Vec3(1, 0.2, 0.3), 80, 5));
    else
      v = std::make_unique<FisheyeMap>(96, 96, view(Vec3(0, 1, 0), 200, 0, Lens::Equisolid));
    const Image shot = rasterize(*v, smooth_env);
    const LatLongMap ll(256, 128);
    const Image embedded = resample({shot, *v, kId}, ll, kId);
    ASSERT_EQ(embedded.channels, 4);
    ASSERT_EQ(embedded.alpha_channel, 3);
    const SolidAngleTable omega(ll);
    double covered = 0.0;
    for (int j = 0; j < ll.height(); ++j)
      for (int i = 0; i < ll.width(); ++i) {
        const float a = embedded.at(i, j, 3);
        covered += a * omega(i, j);
        if (a == 0.0f) {
          for (int c = 0; c < 3; ++c) ASSERT_EQ(embedded.at(i, j, c), 0.0f);
        }
      }
    const double expected = SolidAngleTable(*v).total();
    EXPECT_NEAR(covered, expected, 0.01 * expected) << v->describe();
  }
}

// envconvert crops a view, records it in metadata (envkit:view), envinfo
// re-reads it, and the view goes back into a lat-long with alpha.
TEST(Views, ToolsRecordAndRereadViews) {
  const fs::path dir = fs::temp_directory_path() / ("envkit_test_views_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  EnvMap m;
  m.param = std::make_unique<LatLongMap>(256, 128);
  m.image = rasterize(*m.param, smooth_env);
  m.image.channel_names = {"R", "G", "B"};
  const std::string src = (dir / "src.exr").string(), v = (dir / "view.exr").string(),
                    fish = (dir / "fish.exr").string(), back = (dir / "back.exr").string();
  save_envmap(src, m);
  auto r = test::run_tool("envconvert",
                          {src, "-o", v, "--to", "perspective", "--view-dir", "90,0", "--fov", "70", "--aspect", "2",
                           "--size", "64", "--roll", "12", "-q"},
                          dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const EnvMap loaded = load_envmap(v);
  ASSERT_EQ(loaded.param->kind(), Kind::Perspective);
  EXPECT_EQ(loaded.image.width, 64);
  EXPECT_EQ(loaded.image.height, 32);
  ASSERT_NE(loaded.param->view(), nullptr);
  EXPECT_LT(angle_between(loaded.param->view()->forward, Vec3(1, 0, 0)), 1e-12);
  EXPECT_DOUBLE_EQ(loaded.param->view()->roll_degrees, 12.0);
  EXPECT_DOUBLE_EQ(loaded.param->view()->fov_degrees, 70.0);
  r = test::run_tool("envinfo", {v}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("perspective"), std::string::npos) << r.out;
  r = test::run_tool(
      "envconvert",
      {src, "-o", fish, "--to", "fisheye", "--lens", "stereographic", "--fov", "200", "--size", "64", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(load_envmap(fish).param->view()->lens, Lens::Stereographic);
  r = test::run_tool("envconvert", {fish, "-o", back, "--to", "latlong", "--size", "64", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(load_envmap(back).image.channels, 4);
  // View options without a view are a usage error.
  r = test::run_tool("envconvert", {src, "-o", (dir / "x.exr").string(), "--to", "cube", "--fov", "90"}, dir);
  EXPECT_EQ(r.code, 2);
  fs::remove_all(dir);
}
