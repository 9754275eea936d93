#pragma once
/// @file distribution_hierarchical.h
/// Sum pyramid (a mip-map of sums) with hierarchical sample warping, Clarberg, Jarosz, Akenine-Moeller and
/// Jensen, "Wavelet Importance Sampling", SIGGRAPH 2005.
///
/// Structure
/// ---------
/// Level 0 holds the W x H weights; level k + 1 has ceil(w_k / 2) x ceil(h_k / 2) nodes, node (i, j) being the
/// sum of children (2i + dx, 2j + dy), dx, dy in {0, 1}; the top level is 1 x 1 (at least one level above the
/// weights). Children that fall outside an odd-sized level are implicit zeros. So ANY size is handled exactly:
/// power-of-two squares give the usual quadtree, 2:1 lat-long maps end in a 2 x 1 level under the root, odd
/// sizes get partial nodes on their last column/row. Trade-off against the alternatives: padding to a power of
/// two square would waste up to ~3x memory on unlucky sizes (and a square for 2:1 maps doubles it); a kd split
/// over integer ranges needs 2 levels per halving and 8 bytes/texel. Ceil-halving costs one partial node per
/// level edge (a few zero floats) and keeps ~4/3 floats per texel.
/// Each level is stored blocked by parent: the four children of a node are adjacent (one 16-byte load, one
/// cache line per level when sampling).
///
/// Warping
/// -------
/// At each node, from the root down: u.x chooses the left or right column pair in proportion to its sum and is
/// re-uniformised (u.x / p or (u.x - p) / (1 - p)), then u.y chooses top or bottom within that column and is
/// re-uniformised likewise; both are clamped at every level. At level 0 the remaining u is the position inside
/// the texel. The warp is continuous and monotone inside each node, which is what keeps stratification.
/// invert() runs the same choices backwards (exact: each step is affine).
///
/// Precision: node sums are accumulated in double from the level below (pairwise, so the total is accurate to
/// ~1e-16) and stored in float, each node rounded once. A choice only compares a node's own children, so every
/// texel's probability keeps float RELATIVE precision (product of at most ~2 x levels ratios, each within
/// ~2^-24): a texel 1e-9 of the sun beside it is drawn with probability w / sum to ~1e-6, unlike a float CDF.
/// pdf() is w / integral (O(1): the leaf over the root); texel_probability() gives the drawn product.
/// Sums never overflow: maps whose total exceeds 2^120 are stored scaled by a power of two.
#include <envkit/sampling/distribution.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace envkit {

namespace detail {

/// One level of the descent: the children c of the current node decide dx by u.x, then dy by u.y inside the chosen
/// column, re-uniformising both. Returns the chosen child's value (a leaf weight at level 0).
///
/// Decisions compare u x sum with the left (top) sum: one division per axis and level, feeding only the next
/// level. u stays in [0, kOneMinusEpsilon] without a full clamp per step: u <= 1 - 2^-53 and sum > 0 give
/// t = u x sum < sum; on the first branch t <= pred(left) and t / left <= pred(left) / left <= 1 - 2^-53, which
/// rounds to at most 1 - 2^-53; the second branch is entered only with a positive right sum (a zero one would
/// make t < left), but the rounding of left + right can put (t - left) / right at 1, so it is clamped. Every
/// value is >= +0, so this is bit for bit the clamp_decision() of every step. Visited nodes have a positive sum
/// (a positive child is never rounded to a zero float sum, and a zero-sum side is never chosen).
/// (Branch-free and reciprocal variants measured no faster: the branches let the CPU start the next level's
/// loads before the division resolves.)
[[gnu::always_inline]] inline double hierarchical_step(const float* c, double& ux, double& uy, std::size_t& i,
                                                       std::size_t& j) {
  // The four children in double: (c0, c1) and (c2, c3), column sums (left, right) = (c0 + c2, c1 + c3).
#if defined(__SSE2__)
  const __m128d a = _mm_cvtps_pd(_mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(c))));
  const __m128d b = _mm_cvtps_pd(_mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(c + 2))));
  const __m128d columns = _mm_add_pd(a, b);
  const double left = _mm_cvtsd_f64(columns), right = _mm_cvtsd_f64(_mm_unpackhi_pd(columns, columns));
  const auto child = [&](int d) {
    return d == 0   ? _mm_cvtsd_f64(a)
           : d == 1 ? _mm_cvtsd_f64(_mm_unpackhi_pd(a, a))
           : d == 2 ? _mm_cvtsd_f64(b)
                    : _mm_cvtsd_f64(_mm_unpackhi_pd(b, b));
  };
#else
  const double left = double(c[0]) + double(c[2]), right = double(c[1]) + double(c[3]);
  const auto child = [c](int d) { return double(c[d]); };
#endif
  const double tx = ux * (left + right);
  double ty, top, bottom;
  std::size_t dx;
  if (tx < left) {
    dx = 0;
    ux = tx / left;
    ty = uy * left;  // the column's sum: top + bottom
    top = child(0);
    bottom = child(2);
  } else {
    dx = 1;
    ux = std::min(kOneMinusEpsilon, (tx - left) / right);  // (this operand order is one minsd in place)
    ty = uy * right;
    top = child(1);
    bottom = child(3);
  }
  double chosen;
  std::size_t dy;
  if (ty < top) {
    dy = 0;
    uy = ty / top;
    chosen = top;
  } else {
    dy = 1;
    uy = std::min(kOneMinusEpsilon, (ty - top) / bottom);
    chosen = bottom;
  }
  i = 2 * i + dx;
  j = 2 * j + dy;
  return chosen;
}

#if defined(__SSE2__)
/// m ? a : b for a mask m of all ones or all zeros (low lanes).
inline __m128d mask_select(__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); }
#endif

/// hierarchical_step() with selects instead of conditional jumps, bit for bit the same operations on the same
/// values: for group descents (several samples' steps interleaved, HierarchicalDistribution2D::pick_group, the
/// refined tables' pick_group), where what is left of a step's cost is mostly its two decisions, each taken at
/// random, which the CPU cannot predict, and a mispredicted jump would also discard the other samples' work in
/// flight. The divisions are those of the chosen sides only (numerator and denominator are selected first), and
/// std::min(kOneMinusEpsilon, q) is minsd(q, kOneMinusEpsilon).
[[gnu::always_inline]] inline double hierarchical_step_select(const float* c, double& ux, double& uy, std::size_t& i,
                                                              std::size_t& j) {
#if defined(__SSE2__)
  const __m128d a = _mm_cvtps_pd(_mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(c))));      // c0, c1
  const __m128d b = _mm_cvtps_pd(_mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(c + 2))));  // c2, c3
  const __m128d left = _mm_add_pd(a, b), right = _mm_unpackhi_pd(left, left);  // column sums in the low lanes
  const __m128d one_minus = _mm_set_sd(kOneMinusEpsilon);
  const __m128d tx = _mm_mul_sd(_mm_set_sd(ux), _mm_add_sd(left, right));
  const __m128d rx = _mm_cmpnlt_sd(tx, left);  // the right column: !(tx < left)
  const __m128d qx = _mm_div_sd(mask_select(rx, _mm_sub_sd(tx, left), tx), mask_select(rx, right, left));
  ux = _mm_cvtsd_f64(mask_select(rx, _mm_min_sd(qx, one_minus), qx));
  const __m128d ty = _mm_mul_sd(_mm_set_sd(uy), mask_select(rx, right, left));
  const __m128d top = mask_select(rx, _mm_unpackhi_pd(a, a), a), bottom = mask_select(rx, _mm_unpackhi_pd(b, b), b);
  const __m128d ry = _mm_cmpnlt_sd(ty, top);  // the bottom child: !(ty < top)
  const __m128d qy = _mm_div_sd(mask_select(ry, _mm_sub_sd(ty, top), ty), mask_select(ry, bottom, top));
  uy = _mm_cvtsd_f64(mask_select(ry, _mm_min_sd(qy, one_minus), qy));
  i = 2 * i + std::size_t(_mm_movemask_pd(rx) & 1);
  j = 2 * j + std::size_t(_mm_movemask_pd(ry) & 1);
  return _mm_cvtsd_f64(mask_select(ry, bottom, top));
#else
  return hierarchical_step(c, ux, uy, i, j);
#endif
}

}  // namespace detail

/// Hierarchical sample warping through a sum pyramid. ~5.33 bytes per texel (4 for the leaves + 4/3 for sums).
class HierarchicalDistribution2D final : public StoredDistribution2D {
 public:
  /// weights: W x H floats, row-major, row 0 first. Large levels are built in parallel with TBB; results do not
  /// depend on the thread count. Throws Error for a bad size or null weights.
  HierarchicalDistribution2D(const float* weights, int width, int height);
  /// Restores a distribution written by save(); throws Error (naming in.context()) for inconsistent sizes.
  explicit HierarchicalDistribution2D(BlobReader& in);
  void save(BlobWriter& out) const override;

  const char* method() const override { return "hierarchical"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Hierarchical; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  /// Batched sample_texel(), bit for bit: see pick_group().
  void sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const override;
  double pdf(Vec2 uv) const override;
  /// pdf() at texel (x, y) of the grid, which the caller has checked (0 <= x < W, 0 <= y < H).
  double texel_pdf(int x, int y) const { return leaf(x, y) * pdf_scale_; }
  /// The factor of texel_pdf(): pdf = node(0, x, y) x pdf_scale() (W H over the sum of the stored leaves).
  double pdf_scale() const { return pdf_scale_; }
  double texel_probability(int x, int y) const override;
  bool can_invert() const override { return true; }
  Vec2 invert(Vec2 uv) const override;
  std::size_t bytes() const override;

  /// sample_texel() as an inline, non-virtual call, for callers that know the class (SphericalDistribution).
  TexelSample pick(Vec2 u) const;

  /// pick() started at node (i, j) of level k (0 <= k <= levels()) instead of the root: the descent for warps that
  /// chose a node themselves (a product table over the nodes of one level, distribution_refined.h). u is the
  /// position inside that node (clamped like every u); the node's sum must be positive. The returned pdf is the
  /// density w.r.t. uv area GIVEN the node: leaf / node(k, i, j) x W x H.
  TexelSample pick_below(int k, int i, int j, Vec2 u) const;
  /// pick_below() of n <= sampling::kSampleGroup samples, each from its own node: out[s] = pick_below(k,
  /// node[s].x, node[s].y, Vec2(node[s].fx, node[s].fy)) bit for bit, the samples' descents interleaved level by
  /// level (as pick_group) so that their latencies overlap. node[s].pdf is not read.
  void pick_below_group(int k, const TexelSample* node, TexelSample* out, std::size_t n) const;
  /// The probability the stored tables give texel (x, y) among the texels of its node at level k (the product of
  /// the descent's choices below k, recomputed in double); texel_probability(x, y) is this for k = levels().
  double texel_probability_below(int k, int x, int y) const;
  /// pick() of n <= sampling::kSampleGroup samples descending the pyramid together, level by level: each sample's
  /// step at level k prefetches the block it reads at level k - 1, one pass over the group later, so the group's
  /// misses in the large levels overlap.
  void pick_group(const Vec2* u, TexelSample* out, std::size_t n) const;

  /// Number of levels above the weights (the depth of a sample's descent): ceil(log2(max(W, H))), at least 1.
  int levels() const { return static_cast<int>(levels_.size()) - 1; }

  /// Read access for warps that descend the pyramid themselves (product sampling, Clarberg 2008).
  /// Level k has level_width(k) x level_height(k) nodes; level 0 are the (sanitised, possibly power-of-two
  /// scaled) weights, level levels() is the 1 x 1 root. node(k, i, j) is the stored float sum of node (i, j);
  /// nodes outside the level are 0. Children of node (i, j) at level k are (2i + dx, 2j + dy) at level k - 1.
  int level_width(int k) const { return levels_[k].width; }
  int level_height(int k) const { return levels_[k].height; }
  double node(int k, int i, int j) const {
    if (i < 0 || j < 0 || i >= levels_[k].width || j >= levels_[k].height) return 0.0;
    if (k == levels()) return root_;
    return children(k, i >> 1, j >> 1)[(j & 1) * 2 + (i & 1)];
  }

 private:
  /// Throws Error("<context>: invalid pyramid (...)") unless the restored nodes form a pyramid.
  void validate(const std::string& context) const;
  struct Level {
    int width = 0;  // nodes in this level
    int height = 0;
    std::size_t offset = 0;          // start of this level's blocked children array in nodes_ (levels below the top)
    std::size_t blocks_per_row = 0;  // width of the level above: blocks per row of this level's children array
  };
  /// Fills levels_ (and prefetch_top_) from width_ x height_; returns the number of floats nodes_ needs.
  std::size_t layout_levels();
  /// The four children of node (i, j) of level k + 1, stored in level k: {(0,0), (1,0), (0,1), (1,1)}.
  const float* children(int k, int i, int j) const {
    return nodes_.data() + levels_[k].offset + (std::size_t(j) * levels_[k].blocks_per_row + std::size_t(i)) * 4;
  }
  float leaf(int x, int y) const { return children(0, x >> 1, y >> 1)[(y & 1) * 2 + (x & 1)]; }
  /// The descent of pick() and pick_below(): from node (i, j) of level k >= 1 down to a leaf, one hierarchical_step per
  /// level (i, j become the leaf's texel, ux, uy the position left inside it); returns the leaf's stored value.
  /// Prefetches each next level's candidate blocks while reading levels 1..prefetch_top_.
  double descend(int k, std::size_t& i, std::size_t& j, double& ux, double& uy) const;

  TableArray<float> nodes_;    // levels 0 .. top-1, each blocked by parent
  std::vector<Level> levels_;  // levels 0 .. top (top is 1 x 1, its value is the root sum)
  double pdf_scale_ = 0.0;     // pdf = leaf * pdf_scale_ = leaf * W H / (sum of stored leaves)
  double root_ = 0.0;          // the root sum (double)
  int top_level_ = 0;          // levels()
  int prefetch_top_ = 0;       // sample() prefetches the next level's blocks while reading levels 1..prefetch_top_
};

[[gnu::always_inline]] inline double HierarchicalDistribution2D::descend(int k, std::size_t& i, std::size_t& j,
                                                                         double& ux, double& uy) const {
  const float* nodes = nodes_.data();
  const Level* level = levels_.data();
  double leaf = 0.0;
  int m = k - 1;
  // Small top levels: cached, no prefetch.
  for (; m > prefetch_top_; --m)
    leaf = detail::hierarchical_step(nodes + level[m].offset + (j * level[m].blocks_per_row + i) * 4, ux, uy, i, j);
  // Large levels: the next block is one of the four children's blocks, two 32-byte pairs in rows 2j and 2j + 1 of
  // level m - 1; fetching both now hides the miss behind this level's arithmetic.
  // (The second address is formed as an integer: on the last row it lies past the level, which a prefetch may
  // name without faulting but a pointer may not.)
  for (; m >= 0; --m) {
    if (m > 0) {
      const Level& next = level[m - 1];
      const std::uintptr_t pair =
          reinterpret_cast<std::uintptr_t>(nodes + next.offset + (2 * j * next.blocks_per_row + 2 * i) * 4);
      __builtin_prefetch(reinterpret_cast<const void*>(pair));
      __builtin_prefetch(reinterpret_cast<const void*>(pair + next.blocks_per_row * 4 * sizeof(float)));
    }
    leaf = detail::hierarchical_step(nodes + level[m].offset + (j * level[m].blocks_per_row + i) * 4, ux, uy, i, j);
  }
  return leaf;
}

[[gnu::always_inline]] inline TexelSample HierarchicalDistribution2D::pick(Vec2 u) const {
  double ux = sampling::clamp_decision(u.x), uy = sampling::clamp_decision(u.y);
  std::size_t i = 0, j = 0;
  const double leaf = descend(top_level_, i, j, ux, uy);
  TexelSample t;
  t.fx = std::min(kTexelOffsetMax, ux);  // = clamp_offset: ux is in [0, kOneMinusEpsilon]
  t.fy = std::min(kTexelOffsetMax, uy);
  t.pdf = leaf * pdf_scale_;
  t.x = int(i);
  t.y = int(j);
  return t;
}

[[gnu::always_inline]] inline TexelSample HierarchicalDistribution2D::pick_below(int k, int i, int j, Vec2 u) const {
  double ux = sampling::clamp_decision(u.x), uy = sampling::clamp_decision(u.y);
  std::size_t ii = std::size_t(i), jj = std::size_t(j);
  const double top = node(k, i, j);
  const double leaf = k > 0 ? descend(k, ii, jj, ux, uy) : top;
  TexelSample t;
  t.fx = std::min(kTexelOffsetMax, ux);
  t.fy = std::min(kTexelOffsetMax, uy);
  t.pdf = top > 0.0 ? leaf / top * (double(width_) * double(height_)) : 0.0;
  t.x = int(ii);
  t.y = int(jj);
  return t;
}

}  // namespace envkit
