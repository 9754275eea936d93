// The area scatter summed by tiles of the output (ScatterKernel::OutputOrder) against the scatter summed by chunks of
// source rows (Batched): the same shares, so the same output up to the order of the float sums (1e-6 relative per
// texel) on several sources and outputs, odd and tiny ones included, with a 1e9 sun, an alpha channel and a rotation;
// and the same bytes whatever the thread count.
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "resample/src/resample_common.h"
#include "resample_kernel_support.h"
#include "scatter_test_cases.h"

using namespace envkit;
using namespace envkit::testing;
using detail::ScatterKernel;

namespace {

// Largest relative difference over the texels with a solid angle; the texels without one (outside a disk map's
// disks) must be 0 in `got`. The chunked scatter with float sums leaves there the unnormalised sums of the shares that
// fell on them (its sums live in the output, and only texels with a solid angle are normalised); the tiles write
// nothing there, as the chunked scatter with double sums does not.
double difference_where_covered(const Image& got, const Image& want, const Parameterization& dst, bool& blank_zero) {
  const detail::AreaTables tables(dst, dst);
  double worst = 0.0;
  blank_zero = true;
  for (int j = 0; j < got.height; ++j)
    for (int i = 0; i < got.width; ++i)
      for (int c = 0; c < got.channels; ++c) {
        const double x = got.at(i, j, c), y = want.at(i, j, c), scale = std::max(std::abs(x), std::abs(y));
        if (!(tables.dst(i, j) > 0.0))
          blank_zero = blank_zero && x == 0.0;
        else if (scale > 0.0)
          worst = std::max(worst, std::abs(x - y) / scale);
      }
  return worst;
}

void expect_orders_agree(const Image& src, const Parameterization& sp, const Mat3& to_world, const std::string& what) {
  for (const Named& b : scatter_outputs()) {
    const Image want = scatter(src, sp, to_world, *b.p, ScatterKernel::Batched);
    const Image got = scatter(src, sp, to_world, *b.p, ScatterKernel::OutputOrder);
    ASSERT_EQ(got.pixels.size(), want.pixels.size());
    bool blank_zero = false;
    EXPECT_LE(difference_where_covered(got, want, *b.p, blank_zero), 1e-6) << what << " -> " << b.name;
    EXPECT_TRUE(blank_zero) << what << " -> " << b.name;
  }
}

bool same_bytes(const Image& a, const Image& b) {
  return a.pixels.size() == b.pixels.size() &&
         std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)) == 0;
}

}  // namespace

TEST(ScatterOutputOrder, AgreesWithChunksOnEveryCase) { each_scatter_case(expect_orders_agree); }

// The tolerance can fail: a share lost or counted twice moves a texel by far more than a change of 1e-5 relative.
TEST(ScatterOutputOrder, DifferenceMeasureSeesAChange) {
  const LatLongMap fine(512, 256);
  const CubeMap cube(64);
  const Image src = detailed(fine, 3);
  Image got = scatter(src, fine, Mat3(), cube, ScatterKernel::OutputOrder);
  const Image want = scatter(src, fine, Mat3(), cube, ScatterKernel::Batched);
  bool blank_zero = false;
  EXPECT_LE(difference_where_covered(got, want, cube, blank_zero), 1e-6);
  got.pixels[got.pixels.size() / 2] *= 1.00001f;
  EXPECT_GT(difference_where_covered(got, want, cube, blank_zero), 1e-6);
}

// Tiles write disjoint texels and each sums its shares in a fixed order: one thread and two give the same bytes.
TEST(ScatterOutputOrder, SameBytesWhateverTheThreadCount) {
  const LatLongMap fine(1024, 512);
  Image src = detailed(fine, 3);
  for (int c = 0; c < 3; ++c) src.at(300, 100, c) = 1e9f;
  const Mat3 rotation(0.36, 0.48, -0.8, -0.8, 0.6, 0.0, 0.48, 0.64, 0.6);
  const CubeMap cube(128);
  const LatLongMap coarse(256, 128);
  const OctahedralMap octahedral(181);
  const std::vector<const Parameterization*> dsts = {&cube, &coarse, &octahedral};
  for (const Parameterization* dst : dsts)
    for (const Mat3& to_world : {Mat3(), rotation}) {
      Image one, two;
      {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        one = scatter(src, fine, to_world, *dst, ScatterKernel::OutputOrder);
      }
      {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
        two = scatter(src, fine, to_world, *dst, ScatterKernel::OutputOrder);
      }
      EXPECT_TRUE(same_bytes(one, two)) << dst->width() << "x" << dst->height();
    }
}

// Auto takes the tiles for a lat-long source into a cube whose faces the tiles align with, the chunks otherwise.
TEST(ScatterOutputOrder, ChosenForLatLongSourcesIntoAlignedCubes) {
  const LatLongMap latlong(64, 32);
  EXPECT_EQ(detail::scatter_kernel_for(latlong, CubeMap(1024)), ScatterKernel::OutputOrder);
  EXPECT_EQ(detail::scatter_kernel_for(latlong, CubeMap(128)), ScatterKernel::OutputOrder);
  EXPECT_EQ(detail::scatter_kernel_for(latlong, CubeMap(100)), ScatterKernel::Batched);  // faces cut by tiles
  EXPECT_EQ(detail::scatter_kernel_for(LatLongMap(4096, 2048), CubeMap(512)), ScatterKernel::OutputOrder);
  EXPECT_EQ(detail::scatter_kernel_for(LatLongMap(4096, 2048), CubeMap(64)), ScatterKernel::Batched);  // 341 : 1
  EXPECT_EQ(detail::scatter_kernel_for(latlong, LatLongMap(33, 17)), ScatterKernel::Batched);
  EXPECT_EQ(detail::scatter_kernel_for(latlong, OctahedralMap(45)), ScatterKernel::Batched);
  EXPECT_EQ(detail::scatter_kernel_for(latlong, DualParaboloidMap(48, 24)), ScatterKernel::Batched);
  EXPECT_EQ(detail::scatter_kernel_for(CubeMap(16), CubeMap(1024)), ScatterKernel::Batched);
  EXPECT_EQ(detail::scatter_kernel_for(OctahedralMap(33), CubeMap(1024)), ScatterKernel::Batched);
}

// A constant map stays constant through the tiles (each texel is its shares' weighted mean), and the power is the
// chunked scatter's: the same shares, summed in another order.
TEST(ScatterOutputOrder, KeepsAConstantMapConstantAndThePower) {
  const LatLongMap fine(1024, 512);
  Image flat(fine.width(), fine.height(), 3);
  for (int j = 0; j < fine.height(); ++j)
    for (int i = 0; i < fine.width(); ++i) {
      flat.at(i, j, 0) = 2.0f;
      flat.at(i, j, 1) = 0.5f;
      flat.at(i, j, 2) = 1e-3f;
    }
  Image sunny = detailed(fine, 3);
  for (int c = 0; c < 3; ++c) sunny.at(700, 90, c) = 1e9f;
  const std::vector<Named> cubes = {{"cube 64", std::make_shared<CubeMap>(64)},
                                    {"cube 128", std::make_shared<CubeMap>(128)}};
  for (const Named& b : cubes) {
    const Image out = scatter(flat, fine, Mat3(), *b.p, ScatterKernel::OutputOrder);
    for (int j = 0; j < b.p->height(); ++j)
      for (int i = 0; i < b.p->width(); ++i) {
        ASSERT_NEAR(out.at(i, j, 0), 2.0f, 2e-6f) << b.name << " at " << i << "," << j;
        ASSERT_NEAR(out.at(i, j, 2), 1e-3f, 1e-9f) << b.name << " at " << i << "," << j;
      }
    const auto source = total_power(sunny, fine);
    const auto tiles = total_power(scatter(sunny, fine, Mat3(), *b.p, ScatterKernel::OutputOrder), *b.p);
    const auto chunks = total_power(scatter(sunny, fine, Mat3(), *b.p, ScatterKernel::Batched), *b.p);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(tiles[c], chunks[c], 1e-7 * chunks[c]) << b.name;
      EXPECT_NEAR(tiles[c], source[c], 1e-4 * source[c]) << b.name;
    }
  }
}
