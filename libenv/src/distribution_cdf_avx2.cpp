// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from find().
#include <envkit/distribution.h>

#include "avx2_target.h"
#include "distribution_cdf_simd.h"

namespace envkit::detail {

#if defined(ENVKIT_AVX2)

namespace {

// Masks are whole 64-bit lanes of ones or zeros, as the comparisons return them.
ENVKIT_AVX2 inline __m256i load_int(const std::int64_t* p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}
ENVKIT_AVX2 inline void store_int(std::int64_t* p, __m256i v) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), v); }
ENVKIT_AVX2 inline __m256i as_int(__m256d m) { return _mm256_castpd_si256(m); }
/// m ? b : a per lane.
ENVKIT_AVX2 inline __m256i select(__m256i m, __m256i a, __m256i b) { return _mm256_blendv_epi8(a, b, m); }

/// base[index] for the lanes of `lanes`, in double (0 elsewhere). The gather of four floats takes a 32-bit mask: the
/// low half of each 64-bit mask lane.
ENVKIT_AVX2 inline __m256d gather(const float* base, __m256i lanes, __m256i index) {
  const __m256 halves = _mm256_permutevar8x32_ps(_mm256_castsi256_ps(lanes), _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6));
  return _mm256_cvtps_pd(_mm256_mask_i64gather_ps(_mm_setzero_ps(), base, index, _mm256_castps256_ps128(halves), 4));
}

}  // namespace

ENVKIT_AVX2 void cdf_find_group_avx2(const float* base, const std::int64_t* start, const int* bins, const int* split,
                                     const double* u, std::size_t n, int* bin, double* fraction, double* step) {
  constexpr std::size_t G = sampling::kSampleGroup;
  static_assert(G % 4 == 0);
  alignas(32) std::int64_t from[G], sp[G], first[G], count[G], forward[G], lanes[G], next[4];
  alignas(32) double us[G], rs[G];
  const std::size_t vectors = (n + 3) / 4;
  // Lanes past n search an empty range from entry 0 of the first table, and are dropped at the end.
  for (std::size_t k = 0; k < vectors * 4; ++k) {
    const bool real = k < n;
    from[k] = real ? start[k] : start[0];
    sp[k] = real ? split[k] : 0;
    count[k] = real ? bins[k] : 0;
    us[k] = real ? u[k] : 0.0;
    lanes[k] = real ? -1 : 0;
  }
  const __m256i zero = _mm256_setzero_si256(), one = _mm256_set1_epi64x(1);
  const __m256d half_unit = _mm256_set1_pd(0.5), unit = _mm256_set1_pd(1.0);
  // Which part holds the bin (TwoSidedCdf::forward): u < 1/2, or the remaining mass at the split is below r = 1 - u.
  // The forward part searches entries [0, split), the backward part [split, bins).
  for (std::size_t v = 0; v < vectors; ++v) {
    const __m256i origin = load_int(from + 4 * v), s = load_int(sp + 4 * v), real = load_int(lanes + 4 * v);
    const __m256d uv = _mm256_load_pd(us + 4 * v), rv = _mm256_sub_pd(unit, uv);
    const __m256d at_split = gather(base, real, _mm256_add_epi64(origin, s));
    const __m256i f =
        as_int(_mm256_or_pd(_mm256_cmp_pd(uv, half_unit, _CMP_LT_OQ), _mm256_cmp_pd(at_split, rv, _CMP_LT_OQ)));
    store_int(forward + 4 * v, f);
    const __m256i size = load_int(count + 4 * v);
    _mm256_store_pd(rs + 4 * v, rv);
    const __m256i begin = select(f, s, zero);
    store_int(first + 4 * v, begin);
    const __m256i len = select(f, _mm256_sub_epi64(size, s), s);
    store_int(count + 4 * v, _mm256_and_si256(real, len));
    store_int(next, _mm256_add_epi64(origin, _mm256_add_epi64(begin, _mm256_srli_epi64(len, 1))));  // len >= 0
    for (std::int64_t p : next) __builtin_prefetch(base + p);
  }
  // One halving step of every search per round: the group's probes are in flight together, and each step
  // prefetches its search's next probe.
  for (bool more = true; more;) {
    more = false;
    for (std::size_t v = 0; v < vectors; ++v) {
      __m256i f = load_int(first + 4 * v), l = load_int(count + 4 * v);
      const __m256i active = _mm256_cmpgt_epi64(l, zero);
      if (_mm256_testz_si256(active, active)) continue;
      const __m256i origin = load_int(from + 4 * v);
      const __m256i half = _mm256_srli_epi64(l, 1), middle = _mm256_add_epi64(f, half);
      const __m256d e = gather(base, active, _mm256_add_epi64(origin, middle));
      const __m256d uv = _mm256_load_pd(us + 4 * v), rv = _mm256_load_pd(rs + 4 * v);
      const __m256i fw = load_int(forward + 4 * v);
      // TwoSidedCdf::after: forward part !(u < e), backward part e >= r.
      const __m256i after = _mm256_and_si256(
          active, select(fw, as_int(_mm256_cmp_pd(e, rv, _CMP_GE_OQ)), as_int(_mm256_cmp_pd(uv, e, _CMP_NLT_UQ))));
      f = select(after, f, _mm256_add_epi64(middle, one));                     // first = middle + 1
      l = select(after, l, _mm256_sub_epi64(_mm256_sub_epi64(l, half), one));  // len -= half + 1
      l = select(_mm256_andnot_si256(after, active), l, half);                 // len = half
      store_int(first + 4 * v, f);
      store_int(count + 4 * v, l);
      store_int(next, _mm256_add_epi64(origin, _mm256_add_epi64(f, _mm256_srli_epi64(l, 1))));
      for (std::int64_t p : next) __builtin_prefetch(base + p);
      const __m256i left = _mm256_cmpgt_epi64(l, zero);
      more |= !_mm256_testz_si256(left, left);
    }
  }
  // TwoSidedCdf::finish for bin i = first - 1: its step from the two stored entries (forward, backward or the
  // junction bin split - 1) and the fraction of it before u.
  for (std::size_t v = 0; v < vectors; ++v) {
    const __m256i origin = load_int(from + 4 * v), s = load_int(sp + 4 * v), real = load_int(lanes + 4 * v);
    const __m256i i1 = load_int(first + 4 * v), i = _mm256_sub_epi64(i1, one);
    const __m256d ti = gather(base, real, _mm256_add_epi64(origin, i));
    const __m256d ti1 = gather(base, real, _mm256_add_epi64(origin, i1));
    const __m256d rising = _mm256_castsi256_pd(_mm256_cmpgt_epi64(s, i1));  // i + 1 < split
    const __m256d falling =
        _mm256_castsi256_pd(_mm256_xor_si256(_mm256_cmpgt_epi64(s, i), _mm256_set1_epi64x(-1)));  // i >= split
    __m256d st = _mm256_sub_pd(_mm256_sub_pd(unit, ti1), ti);  // the junction bin: (1 - t[i + 1]) - t[i]
    st = _mm256_blendv_pd(st, _mm256_sub_pd(ti1, ti), rising);
    st = _mm256_blendv_pd(st, _mm256_sub_pd(ti, ti1), falling);
    const __m256d uv = _mm256_load_pd(us + 4 * v), rv = _mm256_load_pd(rs + 4 * v);
    const __m256d fw = _mm256_castsi256_pd(load_int(forward + 4 * v));
    const __m256d before = _mm256_blendv_pd(_mm256_sub_pd(ti, rv), _mm256_sub_pd(uv, ti), fw);  // u - t[i] or t[i] - r
    alignas(32) double fr[4], stv[4];
    alignas(32) std::int64_t iv[4];
    _mm256_store_pd(fr, _mm256_div_pd(before, st));
    _mm256_store_pd(stv, st);
    store_int(iv, i);
    for (std::size_t l = 0; l < 4 && 4 * v + l < n; ++l) {
      bin[4 * v + l] = int(iv[l]);
      fraction[4 * v + l] = fr[l];
      step[4 * v + l] = stv[l];
    }
  }
}

#else

void cdf_find_group_avx2(const float*, const std::int64_t*, const int*, const int*, const double*, std::size_t, int*,
                         double*, double*) {}

#endif

}  // namespace envkit::detail
