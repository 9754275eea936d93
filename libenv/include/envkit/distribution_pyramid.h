#pragma once
/// @file distribution_pyramid.h
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
#include <envkit/distribution.h>

#include <vector>

namespace envkit {

/// Hierarchical sample warping through a sum pyramid. ~5.33 bytes per texel (4 for the leaves + 4/3 for sums).
class PyramidDistribution2D final : public Distribution2D {
 public:
  /// weights: W x H floats, row-major, row 0 first. Large levels are built in parallel with TBB; results do not
  /// depend on the thread count. Throws Error for a bad size or null weights.
  PyramidDistribution2D(const float* weights, int width, int height);
  /// Restores a distribution written by save(); throws Error (naming in.context()) for inconsistent sizes.
  explicit PyramidDistribution2D(BlobReader& in);
  void save(BlobWriter& out) const override;

  const char* method() const override { return "pyramid"; }
  DistributionSample sample(Vec2 u) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  bool can_invert() const override { return true; }
  Vec2 invert(Vec2 uv) const override;
  std::size_t bytes() const override;

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
  struct Level {
    int width = 0;            // nodes in this level
    int height = 0;
    std::size_t offset = 0;   // start of this level's blocked children array in nodes_ (levels below the top)
  };
  /// Fills levels_ from width_ x height_; returns the number of floats nodes_ needs.
  std::size_t layout_levels();
  /// The four children of node (i, j) of level k + 1, stored in level k: {(0,0), (1,0), (0,1), (1,1)}.
  const float* children(int k, int i, int j) const {
    return nodes_.data() + levels_[k].offset +
           (std::size_t(j) * std::size_t(levels_[k + 1].width) + std::size_t(i)) * 4;
  }
  float leaf(int x, int y) const { return children(0, x >> 1, y >> 1)[(y & 1) * 2 + (x & 1)]; }

  TableArray<float> nodes_;   // levels 0 .. top-1, each blocked by parent
  std::vector<Level> levels_;  // levels 0 .. top (top is 1 x 1, its value is the root sum)
  double pdf_scale_ = 0.0;     // pdf = leaf * pdf_scale_ = leaf * W H / (sum of stored leaves)
  double root_ = 0.0;          // the root sum (double)
};

}  // namespace envkit
