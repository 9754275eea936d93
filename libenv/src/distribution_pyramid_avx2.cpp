// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from pick().
#include <cstdint>

#include "avx2_target.h"
#include "distribution_pyramid_simd.h"

namespace envkit::detail {

#if defined(ENVKIT_AVX2)

namespace {

/// The four children (c0, c1, c2, c3) of four nodes, in double.
struct Children {
  __m256d c0, c1, c2, c3;
};

/// The low and high floats of four 8-byte pairs, in double: the pairs' floats are reordered to (lows, highs) first.
ENVKIT_AVX2 inline void split_pairs(__m256i pairs, __m256d& low, __m256d& high) {
  const __m256 ordered =
      _mm256_permutevar8x32_ps(_mm256_castsi256_ps(pairs), _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
  low = _mm256_cvtps_pd(_mm256_castps256_ps128(ordered));
  high = _mm256_cvtps_pd(_mm256_extractf128_ps(ordered, 1));
}

/// Children of the blocks with the given indices (in 16-byte blocks from `nodes`): each block is two 8-byte pairs,
/// (c0, c1) and (c2, c3), gathered as doubles.
ENVKIT_AVX2 inline Children load_children(const float* nodes, __m256i block) {
  const auto* base = reinterpret_cast<const double*>(nodes);
  const __m256i first = _mm256_slli_epi64(block, 1);
  const __m256i a = _mm256_castpd_si256(_mm256_i64gather_pd(base, first, 8));
  const __m256i b = _mm256_castpd_si256(_mm256_i64gather_pd(base, _mm256_add_epi64(first, _mm256_set1_epi64x(1)), 8));
  Children c;
  split_pairs(a, c.c0, c.c1);
  split_pairs(b, c.c2, c.c3);
  return c;
}

/// detail::pyramid_step() for four samples: the same products, sums, quotients and clamps, chosen by blends.
/// (min(q, 1 - 2^-53) is std::min(kOneMinusEpsilon, q): both return q only when q is below the bound.)
ENVKIT_AVX2 inline __m256d step(const Children& c, __m256d& ux, __m256d& uy, __m256i& i, __m256i& j) {
  const __m256d bound = _mm256_set1_pd(kOneMinusEpsilon);
  const __m256d left = _mm256_add_pd(c.c0, c.c2), right = _mm256_add_pd(c.c1, c.c3);
  const __m256d tx = _mm256_mul_pd(ux, _mm256_add_pd(left, right));
  const __m256d rx = _mm256_cmp_pd(tx, left, _CMP_NLT_UQ);  // the right column: !(tx < left)
  const __m256d column = _mm256_blendv_pd(left, right, rx);
  const __m256d qx = _mm256_div_pd(_mm256_blendv_pd(tx, _mm256_sub_pd(tx, left), rx), column);
  ux = _mm256_blendv_pd(qx, _mm256_min_pd(qx, bound), rx);
  const __m256d ty = _mm256_mul_pd(uy, column);
  const __m256d top = _mm256_blendv_pd(c.c0, c.c1, rx), bottom = _mm256_blendv_pd(c.c2, c.c3, rx);
  const __m256d ry = _mm256_cmp_pd(ty, top, _CMP_NLT_UQ);  // the bottom child: !(ty < top)
  const __m256d qy = _mm256_div_pd(_mm256_blendv_pd(ty, _mm256_sub_pd(ty, top), ry), _mm256_blendv_pd(top, bottom, ry));
  uy = _mm256_blendv_pd(qy, _mm256_min_pd(qy, bound), ry);
  // 2i + 1 where the mask is set: a set mask lane is the integer -1.
  i = _mm256_sub_epi64(_mm256_add_epi64(i, i), _mm256_castpd_si256(rx));
  j = _mm256_sub_epi64(_mm256_add_epi64(j, j), _mm256_castpd_si256(ry));
  return _mm256_blendv_pd(top, bottom, ry);
}

/// Index (in 16-byte blocks) of the blocks holding the children of nodes (i, j) read at level k. Rows and blocks per
/// row are below 2^32, so the 32-bit multiply's 64-bit product is exact.
ENVKIT_AVX2 inline __m256i block_index(const PyramidWalk& w, int k, __m256i i, __m256i j) {
  const __m256i rows = _mm256_mul_epu32(j, _mm256_set1_epi64x(std::int64_t(w.blocks_per_row[k])));
  return _mm256_add_epi64(_mm256_set1_epi64x(std::int64_t(w.offset[k] / 4)), _mm256_add_epi64(rows, i));
}

ENVKIT_AVX2 inline __m256i load_int(const std::int64_t* p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}
ENVKIT_AVX2 inline void store_int(std::int64_t* p, __m256i v) { _mm256_store_si256(reinterpret_cast<__m256i*>(p), v); }

}  // namespace

ENVKIT_AVX2 void pyramid_pick_group_avx2(const PyramidWalk& w, const Vec2* u, TexelSample* out, std::size_t n) {
  static_assert(sampling::kSampleGroup % 4 == 0);
  const std::size_t vectors = (n + 3) / 4;
  PyramidLanes lanes;
  lanes.start(u, n, vectors * 4);
  double *ux = lanes.ux, *uy = lanes.uy, *leaf = lanes.leaf;
  std::int64_t *is = lanes.i, *js = lanes.j;
  alignas(32) std::int64_t next[4];
  for (int k = w.top - 1; k >= 0; --k) {
    const bool prefetch = k > 0 && k <= w.prefetch_top;  // as pick_group(): the large levels' next blocks
    for (std::size_t v = 0; v < vectors; ++v) {
      __m256d x = _mm256_load_pd(ux + 4 * v), y = _mm256_load_pd(uy + 4 * v);
      __m256i i = load_int(is + 4 * v), j = load_int(js + 4 * v);
      const __m256d chosen = step(load_children(w.nodes, block_index(w, k, i, j)), x, y, i, j);
      _mm256_store_pd(ux + 4 * v, x);
      _mm256_store_pd(uy + 4 * v, y);
      store_int(is + 4 * v, i);
      store_int(js + 4 * v, j);
      if (k == 0) _mm256_store_pd(leaf + 4 * v, chosen);
      if (prefetch) {
        store_int(next, block_index(w, k - 1, i, j));
        for (std::int64_t b : next) __builtin_prefetch(w.nodes + 4 * b);
      }
    }
  }
  lanes.finish(w, out, n);
}

#else

void pyramid_pick_group_avx2(const PyramidWalk&, const Vec2*, TexelSample*, std::size_t) {}

#endif

}  // namespace envkit::detail
