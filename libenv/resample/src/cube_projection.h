#pragma once
// Lat-long texel centres projected into a cube map on vector lanes: the step both directions of a lat-long <-> cube
// conversion repeat for every texel (the scatter projects source centres into the output, the gather output centres
// into the source). Private to libenv's resample group.
//
// The lane kernels evaluate CubeMap::to_image's expressions in its order, on doubles, compiled without FMA
// contraction: they return its positions bit for bit (test_resample_gather holds them to it). The lane operations
// are libenv's (envkit/core/simd/), which the samplers use too.
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>

#include <memory>

namespace envkit::detail {

/// What the lane kernels read: a cube map's faces as tables of 8 (faces 0..5, two unused), how face-local
/// coordinates become pixels, and the rotation applied to each direction first.
struct CubeProjectionTables {
  alignas(64) double axis[3][8], right[3][8], down[3][8];
  alignas(64) double origin_x[8], origin_y[8], max_x[8], max_y[8], centre_x[8], centre_y[8];
  double scale = 1.0;   // pixels per unit of (a + 1) / 2: N, or N - 1 on corner grids
  double offset = 0.0;  // added after scaling: 0.5 on corner grids
  bool corner = false;  // whether local_coord adds the offset
  double rotation[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  bool rotate = false;
};

CubeProjectionTables cube_projection_tables(const CubeMap& cube, const Mat3& rotation, bool rotate);

/// Positions in the cube of the directions (sin_lon[i] cos_lat, sin_lat, cos_lon[i] cos_lat), rotated first when
/// t.rotate, for i in [0, n): CubeMap::to_image(apply(rotation, d)). Lanes when the CPU has them (AVX-512 or AVX2,
/// use_avx512() / use_avx2(), envkit/core/simd/simd_level.h); `lanes` false forces the
/// per-direction reference.
void project_latlong_row_to_cube(const CubeMap& cube, const CubeProjectionTables& t, const double* sin_lon,
                                 const double* cos_lon, double sin_lat, double cos_lat, int n, double* x, double* y,
                                 bool lanes = true);

/// Positions in a cube map of the texel centres of a lat-long map's rows (TexelDirections' directions), rotated
/// first: what the scatter (lat-long -> cube) and the gather (cube -> lat-long) project, a row at a time.
class LatLongRowsInCube {
 public:
  /// The projector when `from` is a lat-long map (Kind::LatLong) and `to` a cube map, else null. `lanes` false: per
  /// direction.
  static std::unique_ptr<LatLongRowsInCube> make(const Parameterization& from, const Parameterization& to,
                                                 const Mat3& rotation, bool rotate, bool lanes = true);
  /// to.to_image of the (rotated) centres of texels [i0, i1) of row j, into x[0, i1 - i0), y[0, i1 - i0).
  void project(int j, int i0, int i1, double* x, double* y) const {
    project_latlong_row_to_cube(cube_, tables_, angles_.sin_lon.data() + i0, angles_.cos_lon.data() + i0,
                                angles_.sin_lat[j], angles_.cos_lat[j], i1 - i0, x, y, lanes_);
  }
  LatLongRowsInCube(const LatLongMap& from, const CubeMap& to, const Mat3& rotation, bool rotate, bool lanes)
      : cube_(to),
        tables_(cube_projection_tables(to, rotation, rotate)),
        angles_(from.centre_angles()),
        lanes_(lanes) {}

 private:
  const CubeMap& cube_;
  CubeProjectionTables tables_;
  LatLongMap::CentreAngles angles_;
  bool lanes_;
};

/// The lane kernels (cube_projection_avx2.cpp, cube_projection_avx512.cpp): whole groups of 4 or 8 directions;
/// they return how many they did (n rounded down to the lane count). Call only when the CPU has the extension.
int project_latlong_row_to_cube_avx2(const CubeProjectionTables& t, const double* sin_lon, const double* cos_lon,
                                     double sin_lat, double cos_lat, int n, double* x, double* y);
int project_latlong_row_to_cube_avx512(const CubeProjectionTables& t, const double* sin_lon, const double* cos_lon,
                                       double sin_lat, double cos_lat, int n, double* x, double* y);

}  // namespace envkit::detail
