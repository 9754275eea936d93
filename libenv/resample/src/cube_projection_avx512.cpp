// project_latlong_row_to_cube on AVX-512 (F + DQ): eight lanes of doubles, face tables looked up by permutes (compiled
// without FMA contraction, see CMakeLists).
#include "cube_projection.h"
// Last: its pragma holds for the rest of the file.
#include <envkit/core/simd/lanes_avx512.h>

#if defined(ENVKIT_AVX512)

#define ENVKIT_LANES_TARGET ENVKIT_AVX512
#include "cube_projection_kernel.inl"
#undef ENVKIT_LANES_TARGET

namespace envkit::detail {

ENVKIT_AVX512 int project_latlong_row_to_cube_avx512(const CubeProjectionTables& t, const double* sin_lon,
                                                     const double* cos_lon, double sin_lat, double cos_lat, int n,
                                                     double* x, double* y) {
  return project_row_lanes<Avx512Lanes>(t, sin_lon, cos_lon, sin_lat, cos_lat, n, x, y);
}

}  // namespace envkit::detail

#else

namespace envkit::detail {
int project_latlong_row_to_cube_avx512(const CubeProjectionTables&, const double*, const double*, double, double, int,
                                       double*, double*) {
  return 0;
}
}  // namespace envkit::detail

#endif
