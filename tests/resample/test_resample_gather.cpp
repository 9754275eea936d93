// The area gather's batched kernel against its per-texel reference (the same outputs within 1e-6 relative; they are
// built to agree bit for bit), and the vector-lane projection of lat-long rows into cube maps against
// CubeMap::to_image, bit for bit, on every lane width the CPU has (the test runs again under ENVKIT_SIMD=avx2).
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "resample/src/cube_projection.h"
#include "resample/src/resample_common.h"
#include "resample_kernel_support.h"

using namespace envkit;
using namespace envkit::testing;
using detail::GatherKernel;

namespace {

const Mat3 kRotation(0.36, 0.48, -0.8, -0.8, 0.6, 0.0, 0.48, 0.64, 0.6);  // a proper rotation, no symmetry

std::vector<Named> cubes() {
  return {
      {"cube 1", std::make_shared<CubeMap>(1)},
      {"cube 2 corner", std::make_shared<CubeMap>(2, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner)},
      {"cube 17 corner",
       std::make_shared<CubeMap>(17, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner)},
      {"cube 32", std::make_shared<CubeMap>(32)},
      {"cube 13 hcross gl", std::make_shared<CubeMap>(13, CubeLayout::HorizontalCross, CubeBasis::GL)},
      {"cube 67", std::make_shared<CubeMap>(67)}};
}

// Bitwise equality of two arrays of doubles (so -0 and 0 differ, as they would in what follows).
bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

// The lanes' positions and the per-direction reference's for directions (sin_lon[i] cos_lat, sin_lat, cos_lon[i]
// cos_lat); expects them bit for bit equal.
void expect_lanes_match(const CubeMap& cube, const Mat3& rotation, bool rotate, const std::vector<double>& sin_lon,
                        const std::vector<double>& cos_lon, double sin_lat, double cos_lat, const std::string& what) {
  const auto t = detail::cube_projection_tables(cube, rotation, rotate);
  const int n = static_cast<int>(sin_lon.size());
  std::vector<double> x(n), y(n), rx(n), ry(n);
  detail::project_latlong_row_to_cube(cube, t, sin_lon.data(), cos_lon.data(), sin_lat, cos_lat, n, x.data(), y.data());
  detail::project_latlong_row_to_cube(cube, t, sin_lon.data(), cos_lon.data(), sin_lat, cos_lat, n, rx.data(),
                                      ry.data(), false);
  EXPECT_TRUE(same_bits(x, rx) && same_bits(y, ry)) << what;
  for (int i = 0; i < n; ++i) {  // the reference is CubeMap::to_image itself
    const Vec3 d(sin_lon[i] * cos_lat, sin_lat, cos_lon[i] * cos_lat);
    const Vec2 p = cube.to_image(rotate ? apply(rotation, d) : d);
    ASSERT_TRUE(p.x == rx[i] && p.y == ry[i]) << what << " i " << i;
  }
}

}  // namespace

TEST(CubeProjectionLanes, MatchToImageBitForBitOnLatLongRows) {
  for (const Named& c : cubes()) {
    const auto& cube = static_cast<const CubeMap&>(*c.p);
    for (const auto& ll : {LatLongMap(515, 259), LatLongMap(64, 32, TexelGrid::Corner), LatLongMap(3, 1),
                           LatLongMap(1, 1), LatLongMap(8, 4)}) {
      const auto a = ll.centre_angles();
      for (const bool rotate : {false, true})
        for (int j = 0; j < ll.height(); ++j)
          expect_lanes_match(
              cube, kRotation, rotate, a.sin_lon, a.cos_lon, a.sin_lat[j], a.cos_lat[j],
              c.name + " <- " + ll.describe() + (rotate ? " rotated" : "") + " row " + std::to_string(j));
    }
  }
}

TEST(CubeProjectionLanes, MatchToImageOnTiesAxesAndTheZeroVector) {
  // Equal components (the face ties, broken towards the first face in order), signed zeros, directions along the
  // axes and the zero vector, which looks at a face's centre.
  const double h = std::sqrt(0.5);
  const std::vector<double> s = {h, -h, 0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 0.0, 1e-300, h, -h, 0.25, 0.0, -0.0, 0.6};
  const std::vector<double> c = {h, h, 1.0, -1.0, 0.0, -0.0, 0.5, -0.5, 0.0, -1e-300, -h, -h, -0.25, -0.0, 0.0, 0.8};
  for (const Named& cb : cubes())
    for (const double lat : {0.0, -0.0, h, -h, 0.5, 1.0, -1.0})
      for (const bool rotate : {false, true}) {
        const auto& cube = static_cast<const CubeMap&>(*cb.p);
        expect_lanes_match(cube, kRotation, rotate, s, c, lat, lat, cb.name + " lat " + std::to_string(lat));
        expect_lanes_match(cube, kRotation, rotate, s, c, lat, 0.0, cb.name + " zero cos_lat");
      }
}

namespace {

Image gather(const Image& src, const Parameterization& sp, const Mat3& to_world, const Parameterization& dst,
             GatherKernel kernel) {
  ResampleOptions opt;
  opt.area_method = AreaMethod::Gather;
  return detail::resample_area_gather({src, sp, to_world}, TexelSource(src, sp), dst, transposed(to_world), opt,
                                      detail::AreaTables(sp, dst), kernel);
}

std::vector<Named> gather_sources() {
  std::vector<Named> maps = cubes();
  maps.push_back({"latlong 64x32", std::make_shared<LatLongMap>(64, 32)});
  maps.push_back({"octahedral 45", std::make_shared<OctahedralMap>(45)});
  return maps;
}

std::vector<Named> gather_outputs() {
  return {{"latlong 256x128", std::make_shared<LatLongMap>(256, 128)},
          {"latlong 259x131 (odd)", std::make_shared<LatLongMap>(259, 131)},
          {"latlong 128x64 corner", std::make_shared<LatLongMap>(128, 64, TexelGrid::Corner)},
          {"latlong 3x1", std::make_shared<LatLongMap>(3, 1)},
          {"latlong 1x1", std::make_shared<LatLongMap>(1, 1)},
          {"cube 24", std::make_shared<CubeMap>(24)},
          {"octahedral 90", std::make_shared<OctahedralMap>(90)}};
}

void expect_kernels_agree(const Image& src, const Parameterization& sp, const Mat3& to_world, const std::string& what) {
  for (const Named& b : gather_outputs()) {
    const Image want = gather(src, sp, to_world, *b.p, GatherKernel::PerTexel);
    const Image got = gather(src, sp, to_world, *b.p, GatherKernel::Batched);
    ASSERT_EQ(got.pixels.size(), want.pixels.size());
    EXPECT_LE(max_relative_difference(got, want), 1e-6) << what << " -> " << b.name;
  }
}

}  // namespace

TEST(ResampleGatherKernels, AgreeOnEveryPair) {
  for (const Named& a : gather_sources()) expect_kernels_agree(detailed(*a.p, 3), *a.p, Mat3(), a.name);
}

TEST(ResampleGatherKernels, AgreeWithAnAlphaChannel) {
  const CubeMap cube(40);
  expect_kernels_agree(detailed(cube, 4), cube, Mat3(), "cube 40 RGBA");
}

TEST(ResampleGatherKernels, AgreeWithA1e9Sun) {
  for (const Named& a : gather_sources()) {
    Image src = detailed(*a.p, 3);
    const int i = a.p->width() / 3, j = a.p->height() / 3;
    for (int c = 0; c < 3; ++c) src.at(i, j, c) = 1e9f;
    expect_kernels_agree(src, *a.p, Mat3(), a.name + " with a 1e9 sun");
  }
}

TEST(ResampleGatherKernels, AgreeUnderRotation) {
  for (const Named& a : gather_sources()) expect_kernels_agree(detailed(*a.p, 3), *a.p, kRotation, a.name + " rotated");
}

// The tolerance can fail: one texel changed by 1e-5 relative is seen.
TEST(ResampleGatherKernels, DifferenceMeasureSeesAChange) {
  const CubeMap cube(32);
  const LatLongMap ll(256, 128);
  const Image src = detailed(cube, 3);
  Image got = gather(src, cube, Mat3(), ll, GatherKernel::Batched);
  const Image want = gather(src, cube, Mat3(), ll, GatherKernel::PerTexel);
  EXPECT_LE(max_relative_difference(got, want), 1e-6);
  got.pixels[got.pixels.size() / 2] *= 1.00001f;
  EXPECT_GT(max_relative_difference(got, want), 1e-6);
}

// TexelSource::interior_bilinear_taps, which the gather takes for every magnified texel, tells whether a position's
// 2 x 2 texels lie on one chart by a multiply instead of divisions: the same answers and taps as the divisions give,
// at every texel and next to every edge of cube faces of several sizes (1 and powers of two included), strips
// horizontal and vertical, and a lat-long (one chart).
TEST(InteriorBilinearTaps, AgreeWithTheDivisions) {
  const std::vector<Named> maps = {{"cube 1", std::make_shared<CubeMap>(1)},
                                   {"cube 2", std::make_shared<CubeMap>(2)},
                                   {"cube 3", std::make_shared<CubeMap>(3)},
                                   {"cube 7 hstrip", std::make_shared<CubeMap>(7, CubeLayout::HorizontalStrip)},
                                   {"cube 64", std::make_shared<CubeMap>(64)},
                                   {"cube 67", std::make_shared<CubeMap>(67)},
                                   {"cube 1024", std::make_shared<CubeMap>(1024)},
                                   {"latlong 37x19", std::make_shared<LatLongMap>(37, 19)}};
  for (const Named& m : maps) {
    const Parameterization& p = *m.p;
    const Image img(p.width(), p.height(), 1);
    const TexelSource source(img, p);
    const int cell = p.tap_cell(), W = p.width(), H = p.height();
    ASSERT_GE(cell, 0) << m.name;
    int inside = 0, outside = 0;
    // Every texel of the small maps; of cube 1024 the rows and columns next to face edges and some others.
    const auto wanted = [&](int k, int n) { return n <= 512 || k % 1024 <= 1 || k % 1024 >= 1022 || k % 97 == 0; };
    for (int j = 0; j < H; ++j) {
      if (!wanted(j, H)) continue;
      for (int i = 0; i < W; ++i) {
        if (!wanted(i, W)) continue;
        for (const double d : {0.0, 0.25, 0.999}) {
          const Vec2 q(i + 0.5 + d, j + 0.5 + d);
          const int i0 = i, j0 = j;  // the texels q's taps start from
          const bool expected =
              i0 + 1 < W && j0 + 1 < H && (cell == 0 || (i0 / cell == (i0 + 1) / cell && j0 / cell == (j0 + 1) / cell));
          Tap taps[4];
          const bool got = source.interior_bilinear_taps(q, taps);
          ASSERT_EQ(got, expected) << m.name << " at " << q.x << ", " << q.y;
          if (got) {
            ASSERT_EQ(taps[0].index, std::size_t(j0) * W + i0) << m.name;
            ++inside;
          } else {
            ++outside;
          }
        }
      }
    }
    if (W > 2 && H > 2) EXPECT_GT(inside, 0) << m.name;
    EXPECT_GT(outside, 0) << m.name;
  }
}
