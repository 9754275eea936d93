// project_latlong_row_to_cube on AVX-512 (F + DQ): eight lanes of doubles, face tables looked up by permutes (compiled
// without FMA contraction, see CMakeLists).
#include "cube_projection.h"

#if defined(__x86_64__) && defined(__GNUC__)
#if !defined(__clang__)
// GCC 12's AVX-512 headers start masked operations from _mm512_undefined_*(), which -Wmaybe-uninitialized reports
// wherever they are inlined (GCC bug 105593); the value is never read.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#define ENVKIT_RESAMPLE_AVX512 __attribute__((target("avx512f,avx512dq")))

namespace envkit::detail {
namespace {

struct Avx512Lanes {
  static constexpr int kWidth = 8;
  using D = __m512d;
  using M = __mmask8;
  using I = __m512i;
  ENVKIT_RESAMPLE_AVX512 static D load(const double* p) { return _mm512_loadu_pd(p); }
  ENVKIT_RESAMPLE_AVX512 static void store(double* p, D v) { _mm512_storeu_pd(p, v); }
  ENVKIT_RESAMPLE_AVX512 static D set(double v) { return _mm512_set1_pd(v); }
  ENVKIT_RESAMPLE_AVX512 static D add(D a, D b) { return _mm512_add_pd(a, b); }
  ENVKIT_RESAMPLE_AVX512 static D mul(D a, D b) { return _mm512_mul_pd(a, b); }
  ENVKIT_RESAMPLE_AVX512 static D div(D a, D b) { return _mm512_div_pd(a, b); }
  ENVKIT_RESAMPLE_AVX512 static D abs(D a) { return _mm512_abs_pd(a); }
  ENVKIT_RESAMPLE_AVX512 static M less(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_LT_OQ); }
  ENVKIT_RESAMPLE_AVX512 static M at_least(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ); }
  ENVKIT_RESAMPLE_AVX512 static M greater(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ); }
  ENVKIT_RESAMPLE_AVX512 static M both(M a, M b) { return static_cast<M>(a & b); }
  ENVKIT_RESAMPLE_AVX512 static D pick(M m, D yes, D no) { return _mm512_mask_blend_pd(m, no, yes); }
  /// Small whole numbers held as doubles, as 64-bit lane indices.
  ENVKIT_RESAMPLE_AVX512 static I index(D v) { return _mm512_cvttpd_epi64(v); }
  /// table[f] per lane: the eight-entry table is one register, indexed by a permute.
  ENVKIT_RESAMPLE_AVX512 static D lookup(const double* table, I f) {
    return _mm512_permutexvar_pd(f, _mm512_load_pd(table));
  }
};

}  // namespace
}  // namespace envkit::detail

#define ENVKIT_LANES_TARGET ENVKIT_RESAMPLE_AVX512
#include "cube_projection_kernel.inl"
#undef ENVKIT_LANES_TARGET

namespace envkit::detail {

ENVKIT_RESAMPLE_AVX512 int project_latlong_row_to_cube_avx512(const CubeProjectionTables& t, const double* sin_lon,
                                                              const double* cos_lon, double sin_lat, double cos_lat,
                                                              int n, double* x, double* y) {
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
