// project_latlong_row_to_cube on AVX2: four lanes of doubles (compiled without FMA contraction, see CMakeLists).
#include "cube_projection.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ENVKIT_RESAMPLE_AVX2 __attribute__((target("avx2")))

namespace envkit::detail {
namespace {

struct Avx2Lanes {
  static constexpr int kWidth = 4;
  using D = __m256d;
  using M = __m256d;  // whole lanes of ones where true
  using I = __m256i;
  ENVKIT_RESAMPLE_AVX2 static D load(const double* p) { return _mm256_loadu_pd(p); }
  ENVKIT_RESAMPLE_AVX2 static void store(double* p, D v) { _mm256_storeu_pd(p, v); }
  ENVKIT_RESAMPLE_AVX2 static D set(double v) { return _mm256_set1_pd(v); }
  ENVKIT_RESAMPLE_AVX2 static D add(D a, D b) { return _mm256_add_pd(a, b); }
  ENVKIT_RESAMPLE_AVX2 static D mul(D a, D b) { return _mm256_mul_pd(a, b); }
  ENVKIT_RESAMPLE_AVX2 static D div(D a, D b) { return _mm256_div_pd(a, b); }
  ENVKIT_RESAMPLE_AVX2 static D abs(D a) { return _mm256_andnot_pd(_mm256_set1_pd(-0.0), a); }
  ENVKIT_RESAMPLE_AVX2 static M less(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
  ENVKIT_RESAMPLE_AVX2 static M at_least(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  ENVKIT_RESAMPLE_AVX2 static M greater(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
  ENVKIT_RESAMPLE_AVX2 static M both(M a, M b) { return _mm256_and_pd(a, b); }
  ENVKIT_RESAMPLE_AVX2 static D pick(M m, D yes, D no) { return _mm256_blendv_pd(no, yes, m); }
  /// Small whole numbers held as doubles, as 64-bit lane indices.
  ENVKIT_RESAMPLE_AVX2 static I index(D v) { return _mm256_cvtepi32_epi64(_mm256_cvttpd_epi32(v)); }
  ENVKIT_RESAMPLE_AVX2 static D lookup(const double* table, I f) { return _mm256_i64gather_pd(table, f, 8); }
};

}  // namespace
}  // namespace envkit::detail

#define ENVKIT_LANES_TARGET ENVKIT_RESAMPLE_AVX2
#include "cube_projection_kernel.inl"
#undef ENVKIT_LANES_TARGET

namespace envkit::detail {

ENVKIT_RESAMPLE_AVX2 int project_latlong_row_to_cube_avx2(const CubeProjectionTables& t, const double* sin_lon,
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
