#pragma once
/// @file product_sampling.h
/// BSDF x cos x environment product sampling by hierarchical warping (Clarberg and Akenine-Moeller, "Practical
/// Product Importance Sampling for Direct Illumination", EG 2008), on top of the environment's sum pyramid.
///
/// Per shading point (prepare):
///  1. Coarse level c of the environment's PyramidDistribution2D: the level whose node grid is nearest (in log2)
///     to `product_resolution` columns (32 -> 32 x 16 nodes on a 2:1 lat-long pyramid; 1 -> the root: plain
///     environment sampling; >= W -> the texels themselves).
///  2. BSDF table at that level: for every coarse node, b = the mean of mean_rgb(eval(wo, wi)) over an S x S
///     stratified set of directions inside the node, uniform in solid angle (lat-long: longitude and cos theta
///     at cell centres of an S x S split of the node; S = Options::points_per_axis, default 2 up to 16 columns
///     and 1 above). Nodes whose bounding cone (centre + an angle bound from 16 points per edge plus half their
///     largest gap) lies entirely below the shading horizon get b = 0 EXACTLY (eval is identically 0 there);
///     every other node gets b + floor, floor = Options::floor_fraction (default 0.02) x the mean b over those
///     nodes. The floor makes the table positive wherever eval can be positive, so the estimator is unbiased
///     even where the S x S points miss a narrow lobe (its worst-case weight is bounded by the floor).
///  3. Product weights P(i, j) = env_node(c, i, j) x b(i, j), a double sum pyramid over them up to 1 x 1 with
///     the environment pyramid's ceil-halving layout.
///  Lobe refinement (lat-long tables, Options::lobe_nodes > 0, resolution > 1): when the material's lobe is a
///     cone narrower than ~80 degrees around the mirror direction r (half-angle 2 atan(lobe_extent x alpha_eff),
///     alpha_eff = sqrt(1 / (4 pi cos_o pdf(wo, r))), the GGX alpha of a visible-normal-sampled GGX lobe), the
///     coarse table evaluates NO BSDF: b = 0 on every node touching the hemisphere, and its floor is the BSDF
///     away from the lobe (mean eval at the normal and 4 directions 60 degrees from it, outside the cone) or
///     floor_fraction x the lobe's mean, whichever is larger. The lobe gets its own level l <= c (about
///     lobe_nodes nodes across the cone; coarser while the rectangle of nodes covering the cone in (theta, phi)
///     holds more than max_lobe_nodes) with b_l per node: eval at the node centre, or (lobe_proxy, default)
///     eval(wo, r) x pi alpha_eff^2 x D_GGX(h; alpha_eff), the lobe's shape up to Fresnel and masking at ~1/5 the
///     cost; nodes farther than the cone plus their half diagonal get 0. Below the lobe level (lobe_descent,
///     default) each child is chosen in proportion to env_child x b(child's centre) (the same proxy), so the
///     sample follows the lobe down to the texels; the sampled density is the mixture
///         pdf(w) ~ floor(coarse node) x env_leaf(x, y) / Omega(x, y)
///                + b_l(lobe node) x env_node(l) x prod_k P_k(child on the path to (x, y)) / Omega(x, y),
///     P_k = env x b of that child over the sum of its siblings' (env alone when no sibling has b > 0; without
///     lobe_descent P_k is env alone and the product telescopes to env_leaf / env_node(l)). It is drawn by
///     choosing the coarse pyramid or the lobe's node list (binary search of its cumulative b x env) with u.x,
///     then descending below the chosen node; pdf() walks the same path (4 lobe values per level). Unbiasedness
///     is unchanged: the floor keeps pdf > 0 on every node that touches the hemisphere, whatever b_l is.
///  Table reuse (Options::reuse_angle > 0): reusable() lets a prepared table serve later shading points of the
///     same material whose normal and world view direction stay within min(reuse_angle, reuse_lobe_fraction x
///     alpha_eff) of the prepared ones; the density is the prepared one (a valid density anywhere), and nodes
///     count as below the horizon only when they lie below it by the margin reuse_angle, so pdf > 0 wherever
///     eval can be positive at any such point. The caller evaluates the BSDF at its own point.
/// Sampling: u is warped down the product pyramid exactly as distribution_pyramid.cpp does (column pair by u.x,
/// then child by u.y, re-uniformised and clamped with sampling::clamp_decision at every level), then down the
/// environment's own levels c-1 .. 0 with its node sums, then uniformly in solid angle inside the texel
/// (lat-long: longitude linear, cos theta linear, rows measured from the nearer pole, as env_sampling.cpp does;
/// octahedral: uniform in the equal-area square).
/// Density (exact, per steradian, world frame):
///     pdf(w) = [P(i, j) / env_node(c, i, j) + b_l(lobe node of (x, y))] x env_leaf(x, y) / Omega(x, y) / Z,
///     Z = sum(P) + sum over lobe nodes of b_l x env_node(l, .)
/// for the texel (x, y) containing w (SphericalDistribution::texel_of after the inverse rotation) and its coarse
/// node (i, j) = (x >> c, y >> c). sample() returns the same formula for the texel it drew, so
/// pdf(sample direction) == sample pdf (bit for bit unless rounding moves a direction across a texel edge). The
/// product levels are double sums (their choices are exact ratios); below c the environment's float node sums
/// are used as PyramidDistribution2D::pdf uses them, so pdf() is the drawn density to ~1e-7 relative per level
/// below c, and integrates to 1 within 1e-6.
/// Unbiasedness: pdf > 0 wherever eval(wo, wi) x importance > 0 (the floor on every node above the horizon).
/// Pure delta materials (the mirror) have no product: prepare() leaves the sampler invalid; use BSDF sampling.
///
/// Cost and rendered efficiency against power MIS: docs/bench_product.md (how they are measured and the figures).
/// Not thread-safe: one sampler per thread (it reuses its buffers); the environment distribution it refers to must
/// outlive it.
#include <envkit/env_sampling.h>
#include <envkit/render/frame.h>
#include <envkit/render/material.h>
#include <envkit/vec.h>

#include <vector>

namespace envkit {
class PyramidDistribution2D;
}

namespace envkit::render {

class ProductSampler {  // one per thread; reuses its buffers
 public:
  struct Options {
    /// S: BSDF evaluations per coarse node = S x S. 0 = automatic: 2 for coarse grids up to 16 columns, 1 (the
    /// node's solid-angle centre) above. Measured (glossy conductor alpha 0.05 .. 0.3 under a sky + sun): at 32+
    /// columns S = 1 gives the same variance as S = 2 at a quarter of the prepare cost; at 8 columns S = 1 misses
    /// lobes (10x the variance of S = 2).
    int points_per_axis = 0;
    double floor_fraction = 0.02;  ///< floor of b, relative to the mean b over nodes above the horizon
    /// Lobe refinement (lat-long tables only; 0 disables it): a lobe narrower than the coarse nodes gets its own
    /// finer level with about this many nodes across the lobe's cone diameter.
    int lobe_nodes = 8;
    /// Lobe cone half-angle = 2 atan(lobe_extent x alpha_eff) around the mirror direction, alpha_eff =
    /// sqrt(1 / (4 pi cos_o pdf(wo, mirror))) (the GGX alpha for a GGX lobe sampled by visible normals).
    double lobe_extent = 6.0;
    int max_lobe_nodes = 256;  ///< coarser lobe level while the lobe rectangle holds more nodes than this
    /// Lobe nodes use the GGX D(h) of alpha_eff scaled to eval at the mirror direction instead of eval
    /// (cheaper; the same shape up to Fresnel and masking; any positive b keeps the estimator unbiased).
    bool lobe_proxy = true;
    /// Below the lobe level, choose each child in proportion to env x the lobe's value at the child's centre
    /// (the same proxy or eval) instead of env alone, so that the sample follows a lobe narrower than the lobe
    /// nodes down to the texels. pdf() walks the same path (one lobe evaluation per child and level).
    bool lobe_descent = true;
    /// Table reuse (radians, 0 = off): a table prepared at one shading point may serve later points of the same
    /// material whose normal and view direction (world) lie within this angle (reusable()); nodes count as below
    /// the horizon only when they lie below it by this margin, so the density stays positive wherever eval can
    /// be positive at any of those points.
    double reuse_angle = 0.0;
    /// ... and within this fraction of the prepared lobe's width alpha_eff (radians), whichever is smaller: a
    /// narrow lobe moves out of its own table sooner.
    double reuse_lobe_fraction = 0.5;
  };

  /// env_hierarchical: a SphericalDistribution whose distribution() is a PyramidDistribution2D, on a lat-long or
  /// octahedral grid (Error otherwise: node bounds need a map continuous across each node, HEALPix's layout is not).
  /// world_from_table: rotation taking table-frame directions to world directions (see vec.h apply()).
  ProductSampler(const SphericalDistribution& env_hierarchical, const Mat3& world_from_table, int product_resolution);
  ProductSampler(const SphericalDistribution& env_hierarchical, const Mat3& world_from_table, int product_resolution,
                 const Options& options);

  /// Builds the per-point table. wo_local in the shading frame (frame.h); the material must outlive the samples.
  /// After prepare, valid() is false when the product is zero everywhere (wo below the horizon, a pure delta
  /// material, no light above the horizon): sample() then returns false and pdf() 0.
  void prepare(const Material& m, const Frame& frame, const Vec3& wo_local);
  bool valid() const { return valid_; }
  /// True when the table prepared last may serve this shading point (Options::reuse_angle > 0, same material,
  /// normal and world view direction within min(reuse_angle, reuse_lobe_fraction x alpha_eff) of the prepared
  /// ones). The density is then the prepared one; evaluate the BSDF at the new point (sample()'s f_cos is for
  /// the prepared point).
  bool reusable(const Material& m, const Frame& frame, const Vec3& wo_local) const;
  /// Ends reuse: reusable() is false until the next prepare() (the integrator calls it when a pixel starts, so
  /// that tables never cross pixels and images do not depend on which pixel a thread rendered before).
  void stop_reuse() { cos_reuse_ = 1.0; }

  /// Warps u in [0,1)^2 (clamped) to a world direction with its density per steradian (> 0). False when not
  /// valid().
  bool sample(Vec2 u, Vec3& wi_world, double& pdf) const;
  /// The same, also returning f_cos = material.eval(wo, wi) (RGB, local frame of prepare()).
  bool sample(Vec2 u, Vec3& wi_world, double& pdf, Vec3& f_cos) const;
  /// Density per steradian with which sample() draws wi_world (0 for a zero or non-finite vector).
  double pdf(const Vec3& wi_world) const;

  /// The coarse level c and its node grid.
  int coarse_level() const { return coarse_level_; }
  int coarse_width() const { return coarse_w_; }
  int coarse_height() const { return coarse_h_; }
  /// S actually used (BSDF evaluations per coarse node: S x S).
  int points_per_axis() const { return options_.points_per_axis; }
  /// After prepare: the lobe level (< coarse_level()) and its node count, or -1 / 0 when the whole table is
  /// the coarse one (wide lobe, resolution 1, octahedral table).
  int lobe_level() const { return lobe_active_ ? lobe_level_ : -1; }
  int lobe_node_count() const { return lobe_active_ ? lobe_rows_ * lobe_cols_ : 0; }

 private:
  struct NodeCone {
    Vec3 centre;           ///< world direction of the node's centre
    double sin_radius = 1;  ///< sin of an upper bound of the angle from centre to any direction of the node
    double radius = kPi;    ///< that bound (radians)
    bool all_sphere = false;  ///< the bound reaches 90 degrees: the node always touches the hemisphere
  };

  void precompute_nodes();
  /// Probability of choosing coarse node (i, j) (0 outside).
  double coarse_probability(int i, int j) const;
  /// Child sums (c00, c10, c01, c11) of node (i, j) at product level m + 1 (m >= 0), or env level k + 1.
  void product_children(int m, int i, int j, double c[4]) const;
  /// Lobe refinement: chooses the level and rectangle and fills lobe_b_ / lobe_cdf_; false = use the coarse
  /// table alone (wide lobe). floor: the b floor of the coarse table in lobe mode.
  /// alpha: the lobe's effective GGX alpha (effective_alpha in product_sampling.cpp; 0 = no lobe).
  bool prepare_lobe(const Material& m, const Frame& frame, const Vec3& wo_local, double alpha, double& floor);
  /// b of the lobe node containing texel (x, y) (0 outside the lobe rectangle or without lobe).
  double lobe_b(int x, int y) const;
  /// Density per steradian of texel (x, y) (the pdf of every direction inside it).
  double texel_pdf(int x, int y) const;
  /// The lobe's value (proxy or mean eval) for a local direction; 0 below the horizon.
  double lobe_value(const Vec3& wi_local) const;
  /// Lobe descent: weights of the four children (level k) of node (i, j) of level k + 1: env x lobe value at
  /// the child's centre, or env alone when no child has a positive lobe value.
  void lobe_children(int k, int i, int j, double w[4]) const;
  /// Lobe descent: probability of reaching texel (x, y) from its lobe-level node.
  double lobe_path_probability(int x, int y) const;

  const SphericalDistribution& env_;
  const PyramidDistribution2D& pyramid_;
  Mat3 world_from_table_;
  Mat3 table_from_world_;
  Options options_;
  int coarse_level_ = 0;
  int coarse_w_ = 1, coarse_h_ = 1;

  // Per coarse node, constant: S x S world directions and the bounding cone.
  std::vector<Vec3> node_points_;
  std::vector<NodeCone> node_cones_;

  // Per shading point.
  std::vector<std::vector<double>> levels_;  // product pyramid: levels_[0] = coarse grid ... levels_.back() = root
  std::vector<int> level_w_, level_h_;
  std::vector<double> bsdf_;                 // b per coarse node (scratch)
  double total_ = 0.0;         // coarse_total_ + lobe_total_
  double coarse_total_ = 0.0;  // sum of the coarse product table
  // Lobe refinement (per shading point): level, rectangle of nodes (rows x cols, columns wrap around), b per
  // node, cumulative b x env node weights.
  bool lobe_active_ = false;
  int lobe_level_ = 0, lobe_row0_ = 0, lobe_rows_ = 0, lobe_col0_ = 0, lobe_cols_ = 0;
  double lobe_total_ = 0.0;
  std::vector<double> lobe_b_, lobe_cdf_;
  double lobe_a2_ = 0.0, lobe_proxy_scale_ = 0.0;  // proxy: alpha_eff^2 and its scale (0: evaluate the BSDF)
  Mat3 local_from_table_;
  // Lobe descent (lat-long): table-frame centre of the nodes of each level <= coarse: (sin lon, cos lon) per
  // column and (sin theta, cos theta) per row.
  std::vector<std::vector<Vec2>> column_centres_, row_centres_;
  bool valid_ = false;
  const Material* material_ = nullptr;
  Frame frame_;
  Vec3 wo_local_;
  Vec3 prepared_wo_world_;
  double cos_reuse_ = 1.0;
};

}  // namespace envkit::render
