// project_latlong_row_to_cube on AVX2: four lanes of doubles (compiled without FMA contraction, see CMakeLists).
#include <envkit/core/simd/lanes_avx2.h>

#include "cube_projection.h"

#if defined(ENVKIT_AVX2)

#define ENVKIT_LANES_TARGET ENVKIT_AVX2
#include "cube_projection_kernel.inl"
#undef ENVKIT_LANES_TARGET

namespace envkit::detail {

ENVKIT_AVX2 int project_latlong_row_to_cube_avx2(const CubeProjectionTables& t, const double* sin_lon,
                                                 const double* cos_lon, double sin_lat, double cos_lat, int n,
                                                 double* x, double* y) {
  return project_row_lanes<Avx2Lanes>(t, sin_lon, cos_lon, sin_lat, cos_lat, n, x, y);
}

}  // namespace envkit::detail

#else

namespace envkit::detail {
int project_latlong_row_to_cube_avx2(const CubeProjectionTables&, const double*, const double*, double, double, int,
                                     double*, double*) {
  return 0;
}
}  // namespace envkit::detail

#endif
