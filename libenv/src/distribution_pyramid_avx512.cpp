// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from pick().
#include <cstdint>

#include "avx512_target.h"
#include "distribution_pyramid_simd.h"

namespace envkit::detail {

#if defined(ENVKIT_AVX512)

namespace {

/// The four children (c0, c1, c2, c3) of eight nodes, in double.
struct Children {
  __m512d c0, c1, c2, c3;
};

/// Children of the blocks with the given indices (in 16-byte blocks from `nodes`): each block is two 8-byte pairs,
/// (c0, c1) and (c2, c3), gathered as doubles and split into their low and high floats.
ENVKIT_AVX512 inline __m512d low_floats(__m512i pairs) {
  return _mm512_cvtps_pd(_mm256_castsi256_ps(_mm512_cvtepi64_epi32(pairs)));
}
ENVKIT_AVX512 inline __m512d high_floats(__m512i pairs) {
  return _mm512_cvtps_pd(_mm256_castsi256_ps(_mm512_cvtepi64_epi32(_mm512_srli_epi64(pairs, 32))));
}
ENVKIT_AVX512 inline Children load_children(const float* nodes, __m512i block) {
  const __m512i first = _mm512_slli_epi64(block, 1);
  const __m512i a = _mm512_castpd_si512(_mm512_i64gather_pd(first, nodes, 8));
  const __m512i b = _mm512_castpd_si512(_mm512_i64gather_pd(_mm512_add_epi64(first, _mm512_set1_epi64(1)), nodes, 8));
  return {low_floats(a), high_floats(a), low_floats(b), high_floats(b)};
}

/// detail::pyramid_step() for eight samples: the same products, sums, quotients and clamps, chosen by masks.
/// (min(q, 1 - 2^-53) is std::min(kOneMinusEpsilon, q): both return q only when q is below the bound.)
ENVKIT_AVX512 inline __m512d step(const Children& c, __m512d& ux, __m512d& uy, __m512i& i, __m512i& j) {
  const __m512d bound = _mm512_set1_pd(kOneMinusEpsilon);
  const __m512i one = _mm512_set1_epi64(1);
  const __m512d left = _mm512_add_pd(c.c0, c.c2), right = _mm512_add_pd(c.c1, c.c3);
  const __m512d tx = _mm512_mul_pd(ux, _mm512_add_pd(left, right));
  const __mmask8 rx = _mm512_cmp_pd_mask(tx, left, _CMP_NLT_UQ);  // the right column: !(tx < left)
  const __m512d column = _mm512_mask_blend_pd(rx, left, right);
  const __m512d qx = _mm512_div_pd(_mm512_mask_sub_pd(tx, rx, tx, left), column);
  ux = _mm512_mask_min_pd(qx, rx, qx, bound);
  const __m512d ty = _mm512_mul_pd(uy, column);
  const __m512d top = _mm512_mask_blend_pd(rx, c.c0, c.c1), bottom = _mm512_mask_blend_pd(rx, c.c2, c.c3);
  const __mmask8 ry = _mm512_cmp_pd_mask(ty, top, _CMP_NLT_UQ);  // the bottom child: !(ty < top)
  const __m512d qy = _mm512_div_pd(_mm512_mask_sub_pd(ty, ry, ty, top), _mm512_mask_blend_pd(ry, top, bottom));
  uy = _mm512_mask_min_pd(qy, ry, qy, bound);
  const __m512i i2 = _mm512_add_epi64(i, i), j2 = _mm512_add_epi64(j, j);
  i = _mm512_mask_add_epi64(i2, rx, i2, one);
  j = _mm512_mask_add_epi64(j2, ry, j2, one);
  return _mm512_mask_blend_pd(ry, top, bottom);
}

/// Index (in 16-byte blocks) of the blocks holding the children of nodes (i, j) read at level k.
ENVKIT_AVX512 inline __m512i block_index(const PyramidWalk& w, int k, __m512i i, __m512i j) {
  const __m512i rows = _mm512_mullo_epi64(j, _mm512_set1_epi64(std::int64_t(w.blocks_per_row[k])));
  return _mm512_add_epi64(_mm512_set1_epi64(std::int64_t(w.offset[k] / 4)), _mm512_add_epi64(rows, i));
}

}  // namespace

ENVKIT_AVX512 void pyramid_pick_group_avx512(const PyramidWalk& w, const Vec2* u, TexelSample* out, std::size_t n) {
  static_assert(sampling::kSampleGroup % 8 == 0);
  const std::size_t vectors = (n + 7) / 8;
  PyramidLanes lanes;
  lanes.start(u, n, vectors * 8);
  double *ux = lanes.ux, *uy = lanes.uy, *leaf = lanes.leaf;
  std::int64_t *is = lanes.i, *js = lanes.j;
  alignas(64) std::int64_t next[8];
  for (int k = w.top - 1; k >= 0; --k) {
    const bool prefetch = k > 0 && k <= w.prefetch_top;  // as pick_group(): the large levels' next blocks
    for (std::size_t v = 0; v < vectors; ++v) {
      __m512d x = _mm512_load_pd(ux + 8 * v), y = _mm512_load_pd(uy + 8 * v);
      __m512i i = _mm512_load_si512(is + 8 * v), j = _mm512_load_si512(js + 8 * v);
      const __m512d chosen = step(load_children(w.nodes, block_index(w, k, i, j)), x, y, i, j);
      _mm512_store_pd(ux + 8 * v, x);
      _mm512_store_pd(uy + 8 * v, y);
      _mm512_store_si512(is + 8 * v, i);
      _mm512_store_si512(js + 8 * v, j);
      if (k == 0) _mm512_store_pd(leaf + 8 * v, chosen);
      if (prefetch) {
        _mm512_store_si512(next, block_index(w, k - 1, i, j));
        for (std::int64_t b : next) __builtin_prefetch(w.nodes + 4 * b);
      }
    }
  }
  lanes.finish(w, out, n);
}

#else

void pyramid_pick_group_avx512(const PyramidWalk&, const Vec2*, TexelSample*, std::size_t) {}

#endif

}  // namespace envkit::detail
