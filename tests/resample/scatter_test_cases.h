#pragma once
// Shared by the area scatter's kernel tests (test_resample_scatter: the chunked kernels against each other;
// test_scatter_output_order: the tiles against the chunks): the scatter forced with a kernel, the sources and outputs,
// and the cases every comparison runs (every source, an alpha channel, a 1e9 sun, a rotation).
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/resample/resample.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "resample/src/resample_common.h"
#include "resample_kernel_support.h"

namespace envkit::testing {

inline Image scatter(const Image& src, const Parameterization& sp, const Mat3& to_world, const Parameterization& dst,
                     detail::ScatterKernel kernel) {
  ResampleOptions opt;
  opt.area_method = AreaMethod::Scatter;
  return detail::resample_area_scatter({src, sp, to_world}, TexelSource(src, sp), dst, transposed(to_world), opt,
                                       detail::AreaTables(sp, dst), kernel);
}

inline const std::vector<Named>& scatter_sources() {
  static const std::vector<Named> maps = {
      {"latlong 512x256", std::make_shared<LatLongMap>(512, 256)},
      {"latlong 515x259 (odd)", std::make_shared<LatLongMap>(515, 259)},
      {"latlong 256x128 corner", std::make_shared<LatLongMap>(256, 128, TexelGrid::Corner)},
      {"latlong 3x1", std::make_shared<LatLongMap>(3, 1)},
      {"latlong 1x1", std::make_shared<LatLongMap>(1, 1)},
      {"cube 67", std::make_shared<CubeMap>(67)},
      {"octahedral 181", std::make_shared<OctahedralMap>(181)}};
  return maps;
}

inline const std::vector<Named>& scatter_outputs() {
  static const std::vector<Named> maps = {
      {"cube 64", std::make_shared<CubeMap>(64)},  // faces of whole tiles: most texels settled without resolving
      {"cube 32", std::make_shared<CubeMap>(32)},
      {"cube 17 corner",
       std::make_shared<CubeMap>(17, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner)},
      {"cube 13 hcross gl", std::make_shared<CubeMap>(13, CubeLayout::HorizontalCross, CubeBasis::GL)},
      {"latlong 160x80", std::make_shared<LatLongMap>(160, 80)},  // more than one tile across
      {"latlong 64x32", std::make_shared<LatLongMap>(64, 32)},
      {"latlong 33x17 corner", std::make_shared<LatLongMap>(33, 17, TexelGrid::Corner)},
      {"latlong 3x1", std::make_shared<LatLongMap>(3, 1)},
      {"latlong 1x1", std::make_shared<LatLongMap>(1, 1)},
      {"octahedral 45", std::make_shared<OctahedralMap>(45)},
      {"paraboloid 48x24", std::make_shared<DualParaboloidMap>(48, 24)},
      {"mirrorball 41", std::make_shared<MirrorBallMap>(41, 41)}};
  return maps;
}

/// A source, its map, its rotation to the world and a name for messages.
using ScatterCheck = std::function<void(const Image&, const Parameterization&, const Mat3&, const std::string&)>;

/// Every source with detail; a lat-long with an alpha channel; every source with a 1e9 sun (hot: splatted exactly,
/// given zero colour in the scatter); a lat-long under a rotation without symmetry.
inline void each_scatter_case(const ScatterCheck& check) {
  for (const Named& a : scatter_sources()) check(detailed(*a.p, 3), *a.p, Mat3(), a.name);
  const LatLongMap rgba(300, 150);
  check(detailed(rgba, 4), rgba, Mat3(), "latlong 300x150 RGBA");
  for (const Named& a : scatter_sources()) {
    Image src = detailed(*a.p, 3);
    const int i = a.p->width() / 3, j = a.p->height() / 3;
    for (int c = 0; c < 3; ++c) src.at(i, j, c) = 1e9f;
    check(src, *a.p, Mat3(), a.name + " with a 1e9 sun");
  }
  const Mat3 rotation(0.36, 0.48, -0.8, -0.8, 0.6, 0.0, 0.48, 0.64, 0.6);
  const LatLongMap fine(400, 200);
  check(detailed(fine, 3), fine, rotation, "latlong 400x200 rotated");
}

}  // namespace envkit::testing
