// Resampling between parameterizations: flux conservation, round trips, orientation, coverage, determinism.
#include <envkit/maps/angular.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

using namespace envkit;

namespace {

using RadianceFn = std::function<Vec3(const Vec3&)>;

// A smooth environment: low-order variation, strictly positive.
Vec3 smooth_env(const Vec3& d) {
  return Vec3(1.0 + 0.5 * d.x + 0.3 * d.y * d.y, 0.8 + 0.4 * std::sin(2.0 * d.z) + 0.2 * d.y,
              0.6 + 0.3 * d.x * d.z + 0.25 * d.y);
}

// Rasterises f at texel centres (exact enough for smooth f; tests of exact averages live in test_probes).
Image rasterize(const Parameterization& p, const RadianceFn& f) {
  Image img(p.width(), p.height(), 3);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec2 q;
      Vec3 d;
      if (!p.covered_point(i, j, q) || !p.to_direction(q, d)) continue;
      const Vec3 v = f(d);
      img.at(i, j, 0) = float(v.x);
      img.at(i, j, 1) = float(v.y);
      img.at(i, j, 2) = float(v.z);
    }
  return img;
}

struct Named {
  std::string name;
  std::shared_ptr<Parameterization> p;
};

// Parameterizations at matched resolution (about 8200 texels with data each).
std::vector<Named> matched_maps() {
  return {{"latlong", std::make_shared<LatLongMap>(128, 64)},
          {"cube-vstrip", std::make_shared<CubeMap>(37)},
          {"cube-hcross-gl", std::make_shared<CubeMap>(37, CubeLayout::HorizontalCross, CubeBasis::GL)},
          {"octahedral", std::make_shared<OctahedralMap>(91)},
          {"angular", std::make_shared<AngularMap>(102, 102)},
          {"mirrorball", std::make_shared<MirrorBallMap>(102, 102)},
          {"paraboloid", std::make_shared<DualParaboloidMap>(144, 72)}};
}

double relative_power_error(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0.0;
  for (std::size_t c = 0; c < std::min(a.size(), b.size()); ++c)
    worst = std::max(worst, std::abs(a[c] - b[c]) / std::max(std::abs(b[c]), 1e-300));
  return worst;
}

// Solid-angle weighted relative RMS difference of the colour channels over texels with data.
double weighted_relative_rmse(const Image& a, const Image& b, const Parameterization& p) {
  const SolidAngleTable omega(p);
  double num = 0.0, den = 0.0;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      const double w = omega(i, j);
      if (w <= 0.0) continue;
      for (int c = 0; c < 3; ++c) {
        const double d = a.at(i, j, c) - b.at(i, j, c);
        num += w * d * d;
        den += w * double(b.at(i, j, c)) * b.at(i, j, c);
      }
    }
  return std::sqrt(num / den);
}

const Mat3 kIdentity = identity3();

}  // namespace

TEST(Resample, AreaKeepsAConstantMapConstantForEveryPair) {
  for (const Named& a : matched_maps()) {
    const Image src = rasterize(*a.p, [](const Vec3&) { return Vec3(2.0, 0.5, 1e-3); });
    for (const Named& b : matched_maps()) {
      const Image out = resample({src, *a.p, kIdentity}, *b.p, kIdentity);
      const SolidAngleTable omega(*b.p);
      for (int j = 0; j < b.p->height(); ++j)
        for (int i = 0; i < b.p->width(); ++i) {
          if (omega(i, j) <= 0.0) continue;
          ASSERT_NEAR(out.at(i, j, 0), 2.0f, 2e-5f) << a.name << " -> " << b.name << " at " << i << "," << j;
          ASSERT_NEAR(out.at(i, j, 2), 1e-3f, 1e-8f) << a.name << " -> " << b.name;
        }
      EXPECT_LT(relative_power_error(total_power(out, *b.p), total_power(src, *a.p)), 1e-5)
          << a.name << " -> " << b.name;
    }
  }
}

// A "sun" in a single source texel, 1e6 over a 1e-3 sky (dynamic range 1e9), much smaller than an output texel:
// `area` keeps the total power within 0.1% (in fact to round-off, as hot texels are splatted exactly).
TEST(Resample, AreaConservesTheFluxOfASubTexelSun) {
  const LatLongMap fine(512, 256);
  Image src = rasterize(fine, [](const Vec3&) { return Vec3(1e-3, 1e-3, 1e-3); });
  for (int c = 0; c < 3; ++c) src.at(301, 77, c) = 1e6f;
  const auto src_power = total_power(src, fine);
  std::vector<Named> outputs = {{"latlong 32x16", std::make_shared<LatLongMap>(32, 16)},
                                {"cube 8", std::make_shared<CubeMap>(8)},
                                {"octahedral 16", std::make_shared<OctahedralMap>(16)},
                                {"angular 24", std::make_shared<AngularMap>(24, 24)},
                                {"mirrorball 24", std::make_shared<MirrorBallMap>(24, 24)},
                                {"paraboloid 32x16", std::make_shared<DualParaboloidMap>(32, 16)},
                                {"latlong 1024x512 (finer)", std::make_shared<LatLongMap>(1024, 512)}};
  for (const Named& o : outputs) {
    const Image out = resample({src, fine, kIdentity}, *o.p, kIdentity);
    EXPECT_LT(relative_power_error(total_power(out, *o.p), src_power), 1e-3) << o.name;
    EXPECT_LT(relative_power_error(total_power(out, *o.p), src_power), 1e-5) << o.name << " (round-off level)";
  }
  // Without the exact splat (everything gathered), a point filter gets this badly wrong: the test can fail.
  ResampleOptions bilinear;
  bilinear.filter = Filter::Bilinear;
  const CubeMap cube(8);
  const Image point = resample({src, fine, kIdentity}, cube, kIdentity, bilinear);
  EXPECT_GT(relative_power_error(total_power(point, cube), src_power), 0.05);
}

TEST(Resample, AreaConservesSmoothMapPowerAcrossAllPairs) {
  for (const Named& a : matched_maps()) {
    const Image src = rasterize(*a.p, smooth_env);
    const auto p0 = total_power(src, *a.p);
    for (const Named& b : matched_maps()) {
      const Image out = resample({src, *a.p, kIdentity}, *b.p, kIdentity);
      EXPECT_LT(relative_power_error(total_power(out, *b.p), p0), 1e-3) << a.name << " -> " << b.name;
    }
  }
}

// Round trips A -> B -> A at matched resolution for every pair and filter, with the bounds they are held to
// (solid-angle weighted relative RMS error of a smooth environment).
TEST(Resample, RoundTripsStayWithinStatedBounds) {
  struct Bound {
    Filter f;
    double rmse;
  };
  // Measured maxima over all 49 pairs: nearest 1.0%, bilinear 0.41%, bicubic 0.38%, area 0.39%.
  const Bound bounds[] = {
      {Filter::Nearest, 0.015}, {Filter::Bilinear, 0.006}, {Filter::Bicubic, 0.006}, {Filter::Area, 0.006}};
  for (const Named& a : matched_maps()) {
    const Image src = rasterize(*a.p, smooth_env);
    for (const Named& b : matched_maps()) {
      for (const Bound& bound : bounds) {
        ResampleOptions opt;
        opt.filter = bound.f;
        const Image mid = resample({src, *a.p, kIdentity}, *b.p, kIdentity, opt);
        const Image back = resample({mid, *b.p, kIdentity}, *a.p, kIdentity, opt);
        const double err = weighted_relative_rmse(back, src, *a.p);
        EXPECT_LT(err, bound.rmse) << a.name << " -> " << b.name << " -> " << a.name << " with "
                                   << filter_name(bound.f);
      }
    }
  }
}

TEST(Resample, RotationMovesContent) {
  // A bright texel seen along +Z, rotated by yaw 90 (+Z -> +X), must land on the texel that sees +X.
  const LatLongMap ll(64, 32);
  Image src(64, 32, 3);
  const Vec2 pz = ll.to_image(Vec3(0, 0, 1));
  for (int c = 0; c < 3; ++c) src.at(int(pz.x), int(pz.y), c) = 100.0f;
  const Mat3 yaw90(0, 0, 1, 0, 1, 0, -1, 0, 0);  // column-vector rotation taking +Z to +X
  ResampleOptions opt;
  opt.filter = Filter::Nearest;
  const Image out = resample({src, ll, yaw90}, ll, kIdentity, opt);
  const Vec2 px = ll.to_image(Vec3(1, 0, 0));
  EXPECT_EQ(out.at(int(px.x), int(px.y), 0), 100.0f);
  EXPECT_EQ(out.at(int(pz.x), int(pz.y), 0), 0.0f);
}

TEST(Resample, DirectionsOutsideACroppedBallGetZeroCoverage) {
  // The ball's lower part is cut off by the image edge: directions it would show get alpha 0, not black light.
  const MirrorBallMap ball(64, 64, 32.0, 20.0, 30.0);
  Image src = rasterize(ball, [](const Vec3&) { return Vec3(1, 1, 1); });
  const LatLongMap ll(64, 32);
  for (Filter f : {Filter::Bilinear, Filter::Area}) {
    ResampleOptions opt;
    opt.filter = f;
    const Image out = resample({src, ball, kIdentity}, ll, kIdentity, opt);
    ASSERT_EQ(out.channels, 4);
    ASSERT_EQ(out.alpha_channel, 3);
    int seen = 0, unseen = 0;
    for (int j = 0; j < 32; ++j)
      for (int i = 0; i < 64; ++i) {
        Vec3 d;
        ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
        const Vec2 p = ball.to_image(d);
        // The ball (centre y 20, radius 30) is cut off above y = 0 and below y = 64.
        if (p.y > 4.0 && p.y < 36.0 && j > 1 && j < 30) {  // well inside, away from wide polar texels
          EXPECT_NEAR(out.at(i, j, 3), 1.0f, 1e-4f) << filter_name(f);
          EXPECT_NEAR(out.at(i, j, 0), 1.0f, 1e-4f) << filter_name(f);
          ++seen;
        } else if (p.y > 68.0 || p.y < -4.0) {  // well outside: no part of the output texel is seen
          EXPECT_EQ(out.at(i, j, 3), 0.0f) << filter_name(f) << " at " << i << "," << j;
          ++unseen;
        }
      }
    EXPECT_GT(seen, 100);
    EXPECT_GT(unseen, 10);
  }
}

TEST(Resample, CubeEdgesHaveNoSeams) {
  // Smooth map -> cube (bilinear) -> fine lat-long (bilinear): the error next to cube edges is no worse than
  // elsewhere, which fails if taps clamp within a face instead of crossing to the neighbour.
  const LatLongMap src_ll(512, 256), out_ll(1024, 512);
  const Image src = rasterize(src_ll, smooth_env);
  for (CubeLayout layout : {CubeLayout::VerticalStrip, CubeLayout::HorizontalCross, CubeLayout::VerticalCross}) {
    const CubeMap cube(16, layout);
    ResampleOptions opt;
    opt.filter = Filter::Bilinear;
    const Image c = resample({src, src_ll, kIdentity}, cube, kIdentity, opt);
    const Image back = resample({c, cube, kIdentity}, out_ll, kIdentity, opt);
    double worst = 0.0;
    for (int j = 0; j < 512; ++j)
      for (int i = 0; i < 1024; ++i) {
        Vec3 d;
        out_ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
        const Vec3 want = smooth_env(d);
        worst = std::max(worst, std::abs(back.at(i, j, 0) - want.x) / want.x);
      }
    EXPECT_LT(worst, 0.01) << layout_name(layout);
  }
}

TEST(Resample, ResultDoesNotDependOnThreadCount) {
  const LatLongMap src_p(256, 128);
  Image src = rasterize(src_p, smooth_env);
  src.at(100, 30, 0) = 1e5f;
  const CubeMap cube(24, CubeLayout::HorizontalCross);
  Image one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = resample({src, src_p, kIdentity}, cube, kIdentity);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = resample({src, src_p, kIdentity}, cube, kIdentity);
  }
  EXPECT_EQ(one.pixels, two.pixels);
}

TEST(Resample, OneTexelMapsWork) {
  const LatLongMap one(1, 1), ll(8, 4);
  Image src(1, 1, 3);
  src.at(0, 0, 0) = 3.0f;
  const Image out = resample({src, one, kIdentity}, ll, kIdentity);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(out.at(i, j, 0), 3.0f, 1e-5f);
  const Image back = resample({out, ll, kIdentity}, one, kIdentity);
  EXPECT_NEAR(back.at(0, 0, 0), 3.0f, 1e-5f);
}

namespace {

// Exact-enough texel averages of f: 8 x 8 sub-samples per texel weighted by the solid-angle density.
Image texel_averages(const Parameterization& p, const RadianceFn& f) {
  Image img(p.width(), p.height(), 3);
  constexpr int n = 8;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec3 sum(0, 0, 0);
      double weight = 0.0;
      for (int b = 0; b < n; ++b)
        for (int a = 0; a < n; ++a) {
          const Vec2 q(i + (a + 0.5) / n, j + (b + 0.5) / n);
          Vec3 d;
          const double w = p.solid_angle_density(q);
          if (w <= 0.0 || !p.to_direction(q, d)) continue;
          sum += w * f(d);
          weight += w;
        }
      if (weight <= 0.0) continue;
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = float(sum[c] / weight);
    }
  return img;
}

// A map with detail at the scale of the coarse texels (so that averaging, not just interpolation, matters).
Vec3 detailed_env(const Vec3& d) {
  const Vec3 s = smooth_env(d);
  const double ripple = 1.0 + 0.5 * std::sin(40.0 * d.x) * std::sin(37.0 * d.y + 1.0) * std::cos(23.0 * d.z);
  return s * ripple;
}

}  // namespace

// Shrinking from fine maps: where Auto scatters, the scatter is held to exact texel averages of a map with detail at
// the output's scale (measured: at most 0.29% relative RMS, as the gather's 0.29%) and conserves power.
TEST(Resample, ShrinkingScatterMatchesExactTexelAverages) {
  const std::vector<Named> sources = {{"latlong 1024x512", std::make_shared<LatLongMap>(1024, 512)},
                                      {"cube 192", std::make_shared<CubeMap>(192)},
                                      {"octahedral 512", std::make_shared<OctahedralMap>(512)}};
  int scattered = 0;
  for (const Named& a : sources) {
    const Image src = texel_averages(*a.p, detailed_env);
    const auto src_power = total_power(src, *a.p);
    for (const Named& b : matched_maps()) {
      if (choose_area_method(*a.p, *b.p, TexelSource(src, *a.p)) != AreaMethod::Scatter) continue;
      ++scattered;
      const Image want = texel_averages(*b.p, detailed_env);
      ResampleOptions gather;
      gather.area_method = AreaMethod::Gather;
      const Image s = resample({src, *a.p, kIdentity}, *b.p, kIdentity);
      const Image g = resample({src, *a.p, kIdentity}, *b.p, kIdentity, gather);
      const double es = weighted_relative_rmse(s, want, *b.p), eg = weighted_relative_rmse(g, want, *b.p);
      EXPECT_LT(es, 0.004) << a.name << " -> " << b.name << " (gather: " << eg << ")";
      EXPECT_LT(es, 1.25 * eg + 5e-4) << a.name << " -> " << b.name << " scatter much worse than gather";
      EXPECT_LT(relative_power_error(total_power(s, *b.p), src_power), 1e-4) << a.name << " -> " << b.name;
    }
  }
  EXPECT_GE(scattered, 12);  // every pair but those into disk maps
}

// The scatter, forced for every output kind (disks included), keeps a constant map constant and its power.
TEST(Resample, ScatterKeepsAConstantMapConstant) {
  const LatLongMap fine(512, 256);
  const Image src = rasterize(fine, [](const Vec3&) { return Vec3(2.0, 0.5, 1e-3); });
  ResampleOptions scatter;
  scatter.area_method = AreaMethod::Scatter;
  for (const Named& b : matched_maps()) {
    const Image out = resample({src, fine, kIdentity}, *b.p, kIdentity, scatter);
    const SolidAngleTable omega(*b.p);
    for (int j = 0; j < b.p->height(); ++j)
      for (int i = 0; i < b.p->width(); ++i) {
        if (omega(i, j) <= 0.0) continue;
        ASSERT_NEAR(out.at(i, j, 0), 2.0f, 2e-5f) << b.name << " at " << i << "," << j;
        ASSERT_NEAR(out.at(i, j, 2), 1e-3f, 1e-8f) << b.name;
      }
    EXPECT_LT(relative_power_error(total_power(out, *b.p), total_power(src, fine)), 1e-4) << b.name;
  }
}

// Rotated scatter: content moves like the gather moves it.
TEST(Resample, ScatterAndGatherAgreeUnderRotation) {
  const LatLongMap fine(1024, 512);
  const Image src = texel_averages(fine, detailed_env);
  const Mat3 rotation(0.36, 0.48, -0.8, -0.8, 0.6, 0.0, 0.48, 0.64, 0.6);  // a proper rotation, no symmetry
  const CubeMap cube(48);
  ResampleOptions scatter, gather;
  scatter.area_method = AreaMethod::Scatter;
  gather.area_method = AreaMethod::Gather;
  const Image s = resample({src, fine, rotation}, cube, kIdentity, scatter);
  const Image g = resample({src, fine, rotation}, cube, kIdentity, gather);
  EXPECT_LT(weighted_relative_rmse(s, g, cube), 0.004);
}

// Corner-sampled outputs (OpenEXR) store texels on the lat-long seam and on cube edges twice; both area methods
// must give the copies one value (else a seam shows), also when a hot texel (splatted exactly) sits on the seam.
TEST(Resample, AreaGivesTwinTexelsOfCornerGridsOneValue) {
  const LatLongMap fine(512, 256);
  Image src = texel_averages(fine, detailed_env);
  const auto make_hot = [&](const Vec3& d) {
    const Vec2 p = fine.to_image(d.normalized());
    for (int c = 0; c < 3; ++c) src.at(int(p.x), int(p.y), c) = 1e5f;
  };
  make_hot(Vec3(0.02, 0.3, 1.0));    // just beside the lat-long seam (u = 0: +Z in the envkit frame)
  make_hot(Vec3(1.0, 1.0, 0.3));     // on the cube edge between +X and +Y
  make_hot(Vec3(-1.0, -1.0, -1.0));  // a cube corner
  const std::vector<Named> corner_maps = {
      {"latlong 64x32 corner", std::make_shared<LatLongMap>(64, 32, TexelGrid::Corner)},
      {"cube 16 corner",
       std::make_shared<CubeMap>(16, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner)}};
  for (const Named& b : corner_maps) {
    // Texels whose centres see the same direction are twins.
    std::vector<std::pair<Vec3, std::pair<int, int>>> centres;
    for (int j = 0; j < b.p->height(); ++j)
      for (int i = 0; i < b.p->width(); ++i) {
        Vec3 d;
        if (b.p->to_direction(Vec2(i + 0.5, j + 0.5), d)) centres.push_back({d.normalized(), {i, j}});
      }
    for (AreaMethod method : {AreaMethod::Gather, AreaMethod::Scatter}) {
      ResampleOptions opt;
      opt.area_method = method;
      const Image out = resample({src, fine, kIdentity}, *b.p, kIdentity, opt);
      int pairs = 0;
      for (std::size_t m = 0; m < centres.size(); ++m)
        for (std::size_t n = m + 1; n < centres.size(); ++n) {
          if ((centres[m].first - centres[n].first).length() > 1e-9) continue;
          const auto [i0, j0] = centres[m].second;
          const auto [i1, j1] = centres[n].second;
          if (j0 == j1 && (j0 == 0 || j0 == b.p->height() - 1) && b.p->kind() == Kind::LatLong) continue;  // poles
          ++pairs;
          for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(out.at(i0, j0, c), out.at(i1, j1, c), 1e-5 * std::abs(out.at(i0, j0, c)) + 1e-6)
                << b.name << (method == AreaMethod::Gather ? " gather" : " scatter") << ": (" << i0 << "," << j0
                << ") vs (" << i1 << "," << j1 << ")";
        }
      // Lat-long: one seam pair per row but the poles; cube: one pair per inner edge texel, three per corner.
      EXPECT_EQ(pairs, b.p->kind() == Kind::LatLong ? 30 : 12 * 14 + 8 * 3) << b.name;
    }
  }
}
