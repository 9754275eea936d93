// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from find().
#include <envkit/distribution.h>

#include "avx512_target.h"
#include "distribution_cdf_simd.h"

namespace envkit::detail {

#if defined(ENVKIT_AVX512)

namespace {

/// base[index] for the lanes of `lanes`, in double (0 elsewhere).
ENVKIT_AVX512 inline __m512d gather(const float* base, __mmask8 lanes, __m512i index) {
  return _mm512_cvtps_pd(_mm512_mask_i64gather_ps(_mm256_setzero_ps(), lanes, index, base, 4));
}

}  // namespace

ENVKIT_AVX512 void cdf_find_group_avx512(const float* base, const std::int64_t* start, const int* bins,
                                         const int* split, const double* u, std::size_t n, int* bin, double* fraction,
                                         double* step) {
  constexpr std::size_t G = sampling::kSampleGroup;
  constexpr std::size_t V = G / 8;
  static_assert(G % 8 == 0);
  alignas(64) std::int64_t from[G], sp[G], first[G], count[G], next[8];
  alignas(64) double us[G], rs[G];
  __mmask8 forward[V] = {}, lanes[V] = {};
  const std::size_t vectors = (n + 7) / 8;
  // Lanes past n search an empty range from entry 0 of the first table, and are dropped at the end.
  for (std::size_t k = 0; k < vectors * 8; ++k) {
    const bool real = k < n;
    from[k] = real ? start[k] : start[0];
    sp[k] = real ? split[k] : 0;
    count[k] = real ? bins[k] : 0;
    us[k] = real ? u[k] : 0.0;
    if (real) lanes[k / 8] = __mmask8(lanes[k / 8] | (1u << (k % 8)));
  }
  const __m512i zero = _mm512_setzero_si512(), one = _mm512_set1_epi64(1);
  const __m512d half_unit = _mm512_set1_pd(0.5), unit = _mm512_set1_pd(1.0);
  // Which part holds the bin (TwoSidedCdf::forward): u < 1/2, or the remaining mass at the split is below r = 1 - u.
  // The forward part searches entries [0, split), the backward part [split, bins).
  for (std::size_t v = 0; v < vectors; ++v) {
    const __m512i origin = _mm512_load_si512(from + 8 * v), s = _mm512_load_si512(sp + 8 * v);
    const __m512d uv = _mm512_load_pd(us + 8 * v), rv = _mm512_sub_pd(unit, uv);
    const __m512d at_split = gather(base, lanes[v], _mm512_add_epi64(origin, s));
    const __mmask8 f = _mm512_cmp_pd_mask(uv, half_unit, _CMP_LT_OQ) | _mm512_cmp_pd_mask(at_split, rv, _CMP_LT_OQ);
    forward[v] = f;
    const __m512i size = _mm512_load_si512(count + 8 * v);
    _mm512_store_pd(rs + 8 * v, rv);
    _mm512_store_si512(first + 8 * v, _mm512_mask_mov_epi64(s, f, zero));
    const __m512i len = _mm512_mask_mov_epi64(_mm512_sub_epi64(size, s), f, s);
    _mm512_store_si512(count + 8 * v, _mm512_maskz_mov_epi64(lanes[v], len));
    _mm512_store_si512(
        next, _mm512_add_epi64(origin, _mm512_add_epi64(_mm512_mask_mov_epi64(s, f, zero), _mm512_srai_epi64(len, 1))));
    for (std::int64_t p : next) __builtin_prefetch(base + p);
  }
  // One halving step of every search per round: the group's probes are in flight together, and each step
  // prefetches its search's next probe.
  for (bool more = true; more;) {
    more = false;
    for (std::size_t v = 0; v < vectors; ++v) {
      __m512i f = _mm512_load_si512(first + 8 * v), l = _mm512_load_si512(count + 8 * v);
      const __mmask8 active = _mm512_cmpgt_epi64_mask(l, zero);
      if (!active) continue;
      const __m512i origin = _mm512_load_si512(from + 8 * v);
      const __m512i half = _mm512_srai_epi64(l, 1), middle = _mm512_add_epi64(f, half);
      const __m512d e = gather(base, active, _mm512_add_epi64(origin, middle));
      const __m512d uv = _mm512_load_pd(us + 8 * v), rv = _mm512_load_pd(rs + 8 * v);
      const __mmask8 fw = forward[v];
      // TwoSidedCdf::after: forward part !(u < e), backward part e >= r.
      const __mmask8 after = active & ((fw & _mm512_cmp_pd_mask(uv, e, _CMP_NLT_UQ)) |
                                       (__mmask8(~fw) & _mm512_cmp_pd_mask(e, rv, _CMP_GE_OQ)));
      const __mmask8 before = active & __mmask8(~after);
      f = _mm512_mask_add_epi64(f, after, middle, one);                     // first = middle + 1
      l = _mm512_mask_sub_epi64(l, after, _mm512_sub_epi64(l, half), one);  // len -= half + 1
      l = _mm512_mask_mov_epi64(l, before, half);                           // len = half
      _mm512_store_si512(first + 8 * v, f);
      _mm512_store_si512(count + 8 * v, l);
      _mm512_store_si512(next, _mm512_add_epi64(origin, _mm512_add_epi64(f, _mm512_srai_epi64(l, 1))));
      for (std::int64_t p : next) __builtin_prefetch(base + p);
      more |= _mm512_cmpgt_epi64_mask(l, zero) != 0;
    }
  }
  // TwoSidedCdf::finish for bin i = first - 1: its step from the two stored entries (forward, backward or the
  // junction bin split - 1) and the fraction of it before u.
  for (std::size_t v = 0; v < vectors; ++v) {
    const __m512i origin = _mm512_load_si512(from + 8 * v), s = _mm512_load_si512(sp + 8 * v);
    const __m512i i = _mm512_sub_epi64(_mm512_load_si512(first + 8 * v), one), i1 = _mm512_add_epi64(i, one);
    const __m512d ti = gather(base, lanes[v], _mm512_add_epi64(origin, i));
    const __m512d ti1 = gather(base, lanes[v], _mm512_add_epi64(origin, i1));
    const __mmask8 rising = _mm512_cmplt_epi64_mask(i1, s), falling = _mm512_cmpge_epi64_mask(i, s);
    __m512d st = _mm512_sub_pd(_mm512_sub_pd(unit, ti1), ti);  // the junction bin: (1 - t[i + 1]) - t[i]
    st = _mm512_mask_sub_pd(st, rising, ti1, ti);
    st = _mm512_mask_sub_pd(st, falling, ti, ti1);
    const __m512d uv = _mm512_load_pd(us + 8 * v), rv = _mm512_load_pd(rs + 8 * v);
    const __m512d before = _mm512_mask_sub_pd(_mm512_sub_pd(ti, rv), forward[v], uv, ti);  // u - t[i] or t[i] - r
    alignas(64) double fr[8], stv[8];
    alignas(64) std::int64_t iv[8];
    _mm512_store_pd(fr, _mm512_div_pd(before, st));
    _mm512_store_pd(stv, st);
    _mm512_store_si512(iv, i);
    for (std::size_t l = 0; l < 8 && 8 * v + l < n; ++l) {
      bin[8 * v + l] = int(iv[l]);
      fraction[8 * v + l] = fr[l];
      step[8 * v + l] = stv[l];
    }
  }
}

#else

void cdf_find_group_avx512(const float*, const std::int64_t*, const int*, const int*, const double*, std::size_t, int*,
                           double*, double*) {}

#endif

}  // namespace envkit::detail
