#pragma once
/// @file distribution_refined.h
/// A coarse distribution over the nodes of one level of a HierarchicalDistribution2D (its "cells"), refined below each
/// cell by that pyramid's own sums: the warp product tables use (lobe_product.h), Conty Estevez and Lecocq 2018's
/// "multiply a coarse level, descend the environment's own finer levels".
///
/// Warp: a pyramid over the cell weights chooses a cell with u (hierarchically, so stratification survives), the
/// position left inside the cell descends the fine pyramid from that cell's node (HierarchicalDistribution2D::
/// pick_below). Probability of texel (x, y) in cell c: P(c) x leaf(x, y) / node(c), P(c) = w(c) / sum(w).
/// pdf() is that ideal ratio, computed exactly as sample() computes a sample's pdf (so the two are equal bit for
/// bit); like the pyramid's own pdf, the product of the descent's float choices matches it to float precision.
/// integral() is 1: the density is normalised by construction (there are no per-texel weights to sum).
/// Cells whose fine node is 0 get weight 0 (they hold no texel that could be drawn); cells with a positive node
/// and weight 0 are never drawn (pdf 0 on their texels): give every cell with light a positive weight where the
/// estimator needs pdf > 0.
/// Not a StoredDistribution2D: it refers to the fine pyramid and is built from it when a table file is loaded.
#include <envkit/sampling/distribution_hierarchical.h>

#include <memory>
#include <span>

namespace envkit {

class RefinedDistribution2D final : public Distribution2D {
 public:
  /// fine: the pyramid to refine with; level: 0 <= level <= fine->levels(); cell_weights: level_width(level) x
  /// level_height(level) weights, row-major (sanitised like every weight). Throws Error for a size mismatch, a
  /// level out of range, or when no cell with light has a positive weight.
  RefinedDistribution2D(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                        std::span<const float> cell_weights);

  const char* method() const override { return "refined"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Refined; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  std::size_t bytes() const override;

  /// sample_texel() as an inline, non-virtual call, for callers that know the class (SphericalDistribution).
  TexelSample pick(Vec2 u) const {
    const TexelSample cell = cells_.pick(u);
    TexelSample t = fine_->pick_below(level_, cell.x, cell.y, Vec2(cell.fx, cell.fy));
    t.pdf = density(t.pdf, cell.pdf);
    return t;
  }
  /// Density w.r.t. uv area of texel (x, y) (0 outside the grid).
  double texel_pdf(int x, int y) const;

 private:
  std::shared_ptr<const HierarchicalDistribution2D> fine_;
  int level_ = 0;
  HierarchicalDistribution2D cells_;
  double cell_area_ = 1.0;  // 1 / (cells' width x height): cell probability = cells_ pdf x cell_area_
  /// The density of a texel from its density given its cell (pick_below's pdf) and its cell's density under
  /// cells_: the one formula of pick() and texel_pdf().
  double density(double given_cell, double cell_pdf) const { return given_cell * (cell_pdf * cell_area_); }
};

}  // namespace envkit
