#pragma once
// Internal to libenv: the lane operations of its vector kernels (lanes_avx2.h says which) on AVX-512 (F + DQ): eight
// lanes of doubles and 64-bit integers; masks are mask registers. Call only when use_avx512() (simd_level.h). Include
// it last: avx512_target.h's pragma holds for the rest of the file.
#include <cstddef>
#include <cstdint>

#include "avx512_target.h"

#if defined(ENVKIT_AVX512)

namespace envkit::detail {

struct Avx512Lanes {
  static constexpr std::size_t kWidth = 8;
  using D = __m512d;
  using I = __m512i;
  using M = __mmask8;
  ENVKIT_AVX512 static D loadd(const double* p) { return _mm512_load_pd(p); }
  ENVKIT_AVX512 static void stored(double* p, D v) { _mm512_store_pd(p, v); }
  /// Unaligned forms of loadd and stored.
  ENVKIT_AVX512 static D loadu(const double* p) { return _mm512_loadu_pd(p); }
  ENVKIT_AVX512 static void storeu(double* p, D v) { _mm512_storeu_pd(p, v); }
  ENVKIT_AVX512 static I loadi(const std::int64_t* p) { return _mm512_load_si512(p); }
  ENVKIT_AVX512 static void storei(std::int64_t* p, I v) { _mm512_store_si512(p, v); }
  ENVKIT_AVX512 static D setd(double x) { return _mm512_set1_pd(x); }
  ENVKIT_AVX512 static I seti(std::int64_t x) { return _mm512_set1_epi64(x); }
  ENVKIT_AVX512 static D add(D a, D b) { return _mm512_add_pd(a, b); }
  ENVKIT_AVX512 static D sub(D a, D b) { return _mm512_sub_pd(a, b); }
  ENVKIT_AVX512 static D mul(D a, D b) { return _mm512_mul_pd(a, b); }
  ENVKIT_AVX512 static D div(D a, D b) { return _mm512_div_pd(a, b); }
  ENVKIT_AVX512 static D min(D a, D b) { return _mm512_min_pd(a, b); }
  ENVKIT_AVX512 static D abs(D a) { return _mm512_abs_pd(a); }
  ENVKIT_AVX512 static I plus(I a, I b) { return _mm512_add_epi64(a, b); }
  ENVKIT_AVX512 static I minus(I a, I b) { return _mm512_sub_epi64(a, b); }
  ENVKIT_AVX512 static I half(I a) { return _mm512_srli_epi64(a, 1); }
  ENVKIT_AVX512 static I times(I i, std::int64_t k) { return _mm512_mullo_epi64(i, _mm512_set1_epi64(k)); }
  ENVKIT_AVX512 static I twice_plus(I i, M m) {
    const I twice = _mm512_add_epi64(i, i);
    return _mm512_mask_add_epi64(twice, m, twice, _mm512_set1_epi64(1));
  }
  ENVKIT_AVX512 static D select(M m, D a, D b) { return _mm512_mask_blend_pd(m, a, b); }
  ENVKIT_AVX512 static I select(M m, I a, I b) { return _mm512_mask_blend_epi64(m, a, b); }
  ENVKIT_AVX512 static M less(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_LT_OQ); }
  ENVKIT_AVX512 static M at_least(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ); }
  ENVKIT_AVX512 static M not_less(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_NLT_UQ); }
  ENVKIT_AVX512 static M greater(D a, D b) { return _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ); }
  ENVKIT_AVX512 static M greater(I a, I b) { return _mm512_cmpgt_epi64_mask(a, b); }
  ENVKIT_AVX512 static M both(M a, M b) { return M(a & b); }
  ENVKIT_AVX512 static M either(M a, M b) { return M(a | b); }
  ENVKIT_AVX512 static M but_not(M a, M b) { return M(~a & b); }
  ENVKIT_AVX512 static bool any(M m) { return m != 0; }
  ENVKIT_AVX512 static M first(std::size_t c) { return M((1u << c) - 1u); }
  /// Small whole numbers held as doubles, as 64-bit lane indices.
  ENVKIT_AVX512 static I index(D v) { return _mm512_cvttpd_epi64(v); }
  /// table[i] per lane, from a table of 8 doubles aligned to 64 bytes: one register, indexed by a permute.
  ENVKIT_AVX512 static D lookup(const double* table, I i) { return _mm512_permutexvar_pd(i, _mm512_load_pd(table)); }
  /// base[index] in double where m, 0 elsewhere.
  ENVKIT_AVX512 static D gather(const float* base, M m, I index) {
    return _mm512_cvtps_pd(_mm512_mask_i64gather_ps(_mm256_setzero_ps(), m, index, base, 4));
  }
  /// The low and high floats of eight 8-byte pairs, in double.
  ENVKIT_AVX512 static void split(I pairs, D& low, D& high) {
    low = _mm512_cvtps_pd(_mm256_castsi256_ps(_mm512_cvtepi64_epi32(pairs)));
    high = _mm512_cvtps_pd(_mm256_castsi256_ps(_mm512_cvtepi64_epi32(_mm512_srli_epi64(pairs, 32))));
  }
  /// Children of the 16-byte blocks `block`: each is two 8-byte pairs, (c0, c1) and (c2, c3), gathered as doubles.
  ENVKIT_AVX512 static void children(const float* nodes, I block, D& c0, D& c1, D& c2, D& c3) {
    const I first = _mm512_slli_epi64(block, 1);
    split(_mm512_castpd_si512(_mm512_i64gather_pd(first, nodes, 8)), c0, c1);
    split(_mm512_castpd_si512(_mm512_i64gather_pd(_mm512_add_epi64(first, _mm512_set1_epi64(1)), nodes, 8)), c2, c3);
  }
};

}  // namespace envkit::detail

#endif
