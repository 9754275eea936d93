#pragma once
// Internal to libenv: the lane operations of its vector kernels (the samplers' distribution_hierarchical_descent.inl
// and distribution_cdf_search.inl, resample's cube_projection_kernel.inl) on AVX2: four lanes of doubles and 64-bit
// integers; masks are whole lanes of ones (the comparisons' results), held as doubles. Call only when use_avx2()
// (simd_level.h).
#include <cstddef>
#include <cstdint>

#include "avx2_target.h"

#if defined(ENVKIT_AVX2)

namespace envkit::detail {

struct Avx2Lanes {
  static constexpr std::size_t kWidth = 4;
  using D = __m256d;
  using I = __m256i;
  using M = __m256d;
  ENVKIT_AVX2 static D loadd(const double* p) { return _mm256_load_pd(p); }
  ENVKIT_AVX2 static void stored(double* p, D v) { _mm256_store_pd(p, v); }
  /// Unaligned forms of loadd and stored.
  ENVKIT_AVX2 static D loadu(const double* p) { return _mm256_loadu_pd(p); }
  ENVKIT_AVX2 static void storeu(double* p, D v) { _mm256_storeu_pd(p, v); }
  ENVKIT_AVX2 static I loadi(const std::int64_t* p) { return _mm256_load_si256(reinterpret_cast<const __m256i*>(p)); }
  ENVKIT_AVX2 static void storei(std::int64_t* p, I v) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), v); }
  ENVKIT_AVX2 static D setd(double x) { return _mm256_set1_pd(x); }
  ENVKIT_AVX2 static I seti(std::int64_t x) { return _mm256_set1_epi64x(x); }
  ENVKIT_AVX2 static D add(D a, D b) { return _mm256_add_pd(a, b); }
  ENVKIT_AVX2 static D sub(D a, D b) { return _mm256_sub_pd(a, b); }
  ENVKIT_AVX2 static D mul(D a, D b) { return _mm256_mul_pd(a, b); }
  ENVKIT_AVX2 static D div(D a, D b) { return _mm256_div_pd(a, b); }
  ENVKIT_AVX2 static D min(D a, D b) { return _mm256_min_pd(a, b); }
  ENVKIT_AVX2 static D abs(D a) { return _mm256_andnot_pd(_mm256_set1_pd(-0.0), a); }
  ENVKIT_AVX2 static I plus(I a, I b) { return _mm256_add_epi64(a, b); }
  ENVKIT_AVX2 static I minus(I a, I b) { return _mm256_sub_epi64(a, b); }
  ENVKIT_AVX2 static I half(I a) { return _mm256_srli_epi64(a, 1); }
  /// i * k for i and k below 2^32 (the 32-bit multiply's 64-bit product is exact).
  ENVKIT_AVX2 static I times(I i, std::int64_t k) { return _mm256_mul_epu32(i, _mm256_set1_epi64x(k)); }
  /// 2i, plus 1 where m: a set mask lane is the integer -1.
  ENVKIT_AVX2 static I twice_plus(I i, M m) { return _mm256_sub_epi64(_mm256_add_epi64(i, i), _mm256_castpd_si256(m)); }
  ENVKIT_AVX2 static D select(M m, D a, D b) { return _mm256_blendv_pd(a, b, m); }
  ENVKIT_AVX2 static I select(M m, I a, I b) { return _mm256_blendv_epi8(a, b, _mm256_castpd_si256(m)); }
  ENVKIT_AVX2 static M less(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
  ENVKIT_AVX2 static M at_least(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
  ENVKIT_AVX2 static M not_less(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_NLT_UQ); }
  ENVKIT_AVX2 static M greater(D a, D b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
  ENVKIT_AVX2 static M greater(I a, I b) { return _mm256_castsi256_pd(_mm256_cmpgt_epi64(a, b)); }
  ENVKIT_AVX2 static M both(M a, M b) { return _mm256_and_pd(a, b); }
  ENVKIT_AVX2 static M either(M a, M b) { return _mm256_or_pd(a, b); }
  ENVKIT_AVX2 static M but_not(M a, M b) { return _mm256_andnot_pd(a, b); }
  ENVKIT_AVX2 static bool any(M m) { return !_mm256_testz_pd(m, m); }
  ENVKIT_AVX2 static M first(std::size_t c) {
    return greater(_mm256_set1_epi64x(std::int64_t(c)), _mm256_setr_epi64x(0, 1, 2, 3));
  }
  /// Small whole numbers held as doubles, as 64-bit lane indices.
  ENVKIT_AVX2 static I index(D v) { return _mm256_cvtepi32_epi64(_mm256_cvttpd_epi32(v)); }
  /// table[i] per lane, from a table of at least 8 doubles.
  ENVKIT_AVX2 static D lookup(const double* table, I i) { return _mm256_i64gather_pd(table, i, 8); }
  /// base[index] in double where m, 0 elsewhere. The gather of four floats takes a 32-bit mask: the low half of each
  /// 64-bit mask lane.
  ENVKIT_AVX2 static D gather(const float* base, M m, I index) {
    const __m256 halves = _mm256_permutevar8x32_ps(_mm256_castpd_ps(m), _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6));
    return _mm256_cvtps_pd(_mm256_mask_i64gather_ps(_mm_setzero_ps(), base, index, _mm256_castps256_ps128(halves), 4));
  }
  /// The low and high floats of four 8-byte pairs, in double (the pairs' floats reordered to lows, highs first).
  ENVKIT_AVX2 static void split(__m256i pairs, D& low, D& high) {
    const __m256 ordered =
        _mm256_permutevar8x32_ps(_mm256_castsi256_ps(pairs), _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
    low = _mm256_cvtps_pd(_mm256_castps256_ps128(ordered));
    high = _mm256_cvtps_pd(_mm256_extractf128_ps(ordered, 1));
  }
  /// Children of the 16-byte blocks `block`: each is two 8-byte pairs, (c0, c1) and (c2, c3), gathered as doubles.
  ENVKIT_AVX2 static void children(const float* nodes, I block, D& c0, D& c1, D& c2, D& c3) {
    const auto* base = reinterpret_cast<const double*>(nodes);
    const I first = _mm256_slli_epi64(block, 1);
    split(_mm256_castpd_si256(_mm256_i64gather_pd(base, first, 8)), c0, c1);
    split(_mm256_castpd_si256(_mm256_i64gather_pd(base, _mm256_add_epi64(first, _mm256_set1_epi64x(1)), 8)), c2, c3);
  }
};

}  // namespace envkit::detail

#endif
