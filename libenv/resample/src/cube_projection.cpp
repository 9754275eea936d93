#include "cube_projection.h"

#include <envkit/core/simd/simd_level.h>

#include <cmath>

namespace envkit::detail {

CubeProjectionTables cube_projection_tables(const CubeMap& cube, const Mat3& rotation, bool rotate) {
  CubeProjectionTables t{};
  const int n = cube.face_size();
  t.corner = cube.grid() == TexelGrid::Corner && n > 1;
  t.scale = t.corner ? double(n - 1) : double(n);
  t.offset = t.corner ? 0.5 : 0.0;
  for (int f = 0; f < 8; ++f) {
    const CubeFace& cf = cube.face(f < 6 ? f : 0);  // lanes 6 and 7 are never looked up
    for (int k = 0; k < 3; ++k) {
      t.axis[k][f] = cf.axis[k];
      t.right[k][f] = cf.right[k];
      t.down[k][f] = cf.down[k];
    }
    t.origin_x[f] = cf.origin_x;
    t.origin_y[f] = cf.origin_y;
    // As CubeMap keeps them: the largest positions inside the face, and where a zero vector looks.
    t.max_x[f] = std::nextafter(static_cast<double>(cf.origin_x + n), 0.0);
    t.max_y[f] = std::nextafter(static_cast<double>(cf.origin_y + n), 0.0);
    t.centre_x[f] = cf.origin_x + 0.5 * n;
    t.centre_y[f] = cf.origin_y + 0.5 * n;
  }
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) t.rotation[a][b] = rotation[a][b];
  t.rotate = rotate;
  return t;
}

void project_latlong_row_to_cube(const CubeMap& cube, const CubeProjectionTables& t, const double* sin_lon,
                                 const double* cos_lon, double sin_lat, double cos_lat, int n, double* x, double* y,
                                 bool lanes) {
  int done = 0;
  if (lanes && use_avx512())
    done = project_latlong_row_to_cube_avx512(t, sin_lon, cos_lon, sin_lat, cos_lat, n, x, y);
  else if (lanes && use_avx2())
    done = project_latlong_row_to_cube_avx2(t, sin_lon, cos_lon, sin_lat, cos_lat, n, x, y);
  Mat3 rotation;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) rotation[a][b] = t.rotation[a][b];
  for (int i = done; i < n; ++i) {  // the reference, and the lanes' remainder
    const Vec3 d(sin_lon[i] * cos_lat, sin_lat, cos_lon[i] * cos_lat);
    const Vec2 p = cube.to_image(t.rotate ? apply(rotation, d) : d);
    x[i] = p.x;
    y[i] = p.y;
  }
}

std::unique_ptr<LatLongRowsInCube> LatLongRowsInCube::make(const Parameterization& from, const Parameterization& to,
                                                           const Mat3& rotation, bool rotate, bool lanes) {
  const LatLongMap* latlong = from.latlong_geometry();
  const auto* cube = dynamic_cast<const CubeMap*>(&to);
  if (from.kind() != Kind::LatLong || !latlong || !cube) return nullptr;
  return std::make_unique<LatLongRowsInCube>(*latlong, *cube, rotation, rotate, lanes);
}

}  // namespace envkit::detail
