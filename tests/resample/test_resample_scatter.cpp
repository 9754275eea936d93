// The area scatter's batched kernel against its per-texel reference kernel: the same outputs (within 1e-6 relative,
// the kernels being built to give the same contributions in the same order) on several map kinds and sizes, odd and
// tiny ones included, a 1e9 sun, an alpha channel and a rotation; and the batched kernel with its shares on vector
// lanes against the same kernel without them, byte for byte.
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
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

// Whether the batched kernel gives the same runs (output texel, double sums) with and without the lanes.
bool same_runs(const Image& src, const Parameterization& sp, const Mat3& to_world, const Parameterization& dst) {
  const detail::AreaTables tables(sp, dst);
  const MapRef ref{src, sp, to_world};
  const auto lanes = detail::scatter_runs(ref, dst, transposed(to_world), {}, tables, ScatterKernel::Batched);
  const auto portable =
      detail::scatter_runs(ref, dst, transposed(to_world), {}, tables, ScatterKernel::BatchedPortable);
  if (lanes.size() != portable.size() || lanes.empty()) return false;
  for (std::size_t r = 0; r < lanes.size(); ++r)
    if (lanes[r].cell != portable[r].cell || lanes[r].sums.size() != portable[r].sums.size() ||
        std::memcmp(lanes[r].sums.data(), portable[r].sums.data(), lanes[r].sums.size() * sizeof(double)) != 0)
      return false;
  return true;
}

void expect_kernels_agree(const Image& src, const Parameterization& sp, const Mat3& to_world, const std::string& what) {
  for (const Named& b : scatter_outputs()) {
    const Image want = scatter(src, sp, to_world, *b.p, ScatterKernel::PerTexel);
    const Image got = scatter(src, sp, to_world, *b.p, ScatterKernel::Batched);
    ASSERT_EQ(got.pixels.size(), want.pixels.size());
    EXPECT_LE(max_relative_difference(got, want), 1e-6) << what << " -> " << b.name;
    // The shares computed on vector lanes (where the CPU has them) are the portable code's doubles: the same runs,
    // bit for bit, and so the same output bytes.
    const Image portable = scatter(src, sp, to_world, *b.p, ScatterKernel::BatchedPortable);
    ASSERT_EQ(portable.pixels.size(), got.pixels.size());
    EXPECT_EQ(std::memcmp(portable.pixels.data(), got.pixels.data(), got.pixels.size() * sizeof(float)), 0)
        << what << " -> " << b.name << ": lanes against portable";
    EXPECT_TRUE(same_runs(src, sp, to_world, *b.p)) << what << " -> " << b.name << ": lanes against portable";
  }
}

}  // namespace

TEST(ResampleScatterKernels, AgreeOnEveryCase) { each_scatter_case(expect_kernels_agree); }

// The tolerance above can fail: a kernel that dropped the second cell of straddling squares would differ by far more.
TEST(ResampleScatterKernels, DifferenceMeasureSeesAChange) {
  const LatLongMap fine(512, 256);
  const CubeMap cube(32);
  const Image src = detailed(fine, 3);
  Image got = scatter(src, fine, Mat3(), cube, ScatterKernel::Batched);
  const Image want = scatter(src, fine, Mat3(), cube, ScatterKernel::PerTexel);
  got.pixels[got.pixels.size() / 2] *= 1.00001f;
  EXPECT_GT(max_relative_difference(got, want), 1e-6);
}

namespace {

// Exact area averages over the output texels, by true footprints: each source texel cut into m x m sub-cells with
// exact solid angles, each sub-cell's flux given to the output texel that sees its centre, then divided by the solid
// angle each output texel received. Only the sub-cells' own size is left of the footprints' error.
Image true_footprint_average(const Image& src, const Parameterization& sp, const Parameterization& dst, int m) {
  const int C = src.channels;
  std::vector<double> sum(std::size_t(dst.width()) * dst.height() * C, 0.0), weight(sum.size() / C, 0.0);
  for (int j = 0; j < sp.height(); ++j)
    for (int i = 0; i < sp.width(); ++i)
      for (int b = 0; b < m; ++b)
        for (int a = 0; a < m; ++a) {
          const double x0 = i + double(a) / m, y0 = j + double(b) / m;
          const double w = sp.solid_angle(x0, y0, x0 + 1.0 / m, y0 + 1.0 / m);
          Vec3 d;
          if (w <= 0.0 || !sp.to_direction(Vec2(x0 + 0.5 / m, y0 + 0.5 / m), d)) continue;
          const Vec2 q = dst.to_image(d);
          const std::size_t t = std::size_t(std::clamp(int(q.y), 0, dst.height() - 1)) * dst.width() +
                                std::size_t(std::clamp(int(q.x), 0, dst.width() - 1));
          weight[t] += w;
          for (int c = 0; c < C; ++c) sum[t * C + c] += w * src.at(i, j, c);
        }
  Image out(dst.width(), dst.height(), C);
  for (std::size_t t = 0; t < weight.size(); ++t)
    for (int c = 0; c < C; ++c) out.pixels[t * C + c] = weight[t] > 0.0 ? float(sum[t * C + c] / weight[t]) : 0.0f;
  return out;
}

// Solid-angle weighted relative RMS of a - b over texels with data, and the largest relative difference.
void relative_errors(const Image& a, const Image& b, const Parameterization& p, double& rms, double& worst) {
  double e = 0.0, total = 0.0;
  worst = 0.0;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      const double w = p.texel_solid_angle(i, j);
      if (w <= 0.0) continue;
      for (int c = 0; c < a.channels; ++c) {
        const double r = (a.at(i, j, c) - b.at(i, j, c)) / std::max(1e-12, double(std::abs(b.at(i, j, c))));
        e += w * r * r;
        total += w;
        worst = std::max(worst, std::abs(r));
      }
    }
  rms = std::sqrt(e / std::max(total, 1e-300));
}

}  // namespace

// What `area`'s scatter gives up: a square of each source texel's solid angle, centred on its projection, stands in
// for the texel's true footprint. Measured against true footprints on a map with
// detail at the output's scale, for output texels 2 to 64 times the source texels' solid angle (12 x 12 sub-cells
// per source texel); the figures are printed (docs/PARAMETERIZATIONS.md quotes them) and bounded.
TEST(ResampleScatterKernels, FootprintErrorAgainstTrueFootprints) {
  const LatLongMap fine(256, 128);
  const Image src = detailed(fine, 3);
  const std::vector<Named> outs = {{"cube 52 (ratio ~2)", std::make_shared<CubeMap>(52)},
                                   {"cube 37 (ratio ~4)", std::make_shared<CubeMap>(37)},
                                   {"cube 18 (ratio ~16)", std::make_shared<CubeMap>(18)},
                                   {"cube 9 (ratio ~64)", std::make_shared<CubeMap>(9)},
                                   {"octahedral 91 (ratio ~4)", std::make_shared<OctahedralMap>(91)},
                                   {"latlong 64x32 (ratio 16)", std::make_shared<LatLongMap>(64, 32)}};
  for (const Named& b : outs) {
    const Image want = true_footprint_average(src, fine, *b.p, 12);
    const Image got = scatter(src, fine, Mat3(), *b.p, ScatterKernel::Batched);
    double rms, worst;
    relative_errors(got, want, *b.p, rms, worst);
    std::printf("footprint error, latlong 256x128 -> %s: relative RMS %.3g, max %.3g\n", b.name.c_str(), rms, worst);
    EXPECT_LT(rms, 0.01) << b.name;
  }
}
