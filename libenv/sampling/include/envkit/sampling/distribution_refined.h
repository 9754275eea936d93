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
///
/// Storage. The cell pyramid (a HierarchicalDistribution2D's nodes over the cell weights, the same floats) lives in a
/// RefinedCellStore: one 64-byte aligned block for any number of distributions over the same cells (product tables:
/// thousands of them, lobe_product.h), each a fixed stride apart, its levels top first. A draw from a cold table
/// then reads the distribution and one block, its top levels in its first lines, instead of chasing the
/// distribution, its pyramid object and that pyramid's level list to the nodes.
#include <envkit/sampling/distribution_hierarchical.h>

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

namespace envkit {

/// The cell pyramids of refined distributions over the cells of one level of one pyramid (see the file comment).
/// Each table is a HierarchicalDistribution2D's node layout over the cells (four children per 16-byte block), its
/// levels stored top first so that a descent reads forward from the table's first line.
class RefinedCellStore {
 public:
  /// Room for `tables` cell pyramids over the nodes of fine's `level` (0 <= level <= fine->levels()). Throws Error
  /// for a null pyramid or a level out of range.
  RefinedCellStore(std::shared_ptr<const HierarchicalDistribution2D> fine, int level, std::size_t tables);
  RefinedCellStore(const RefinedCellStore&) = delete;
  RefinedCellStore& operator=(const RefinedCellStore&) = delete;

  /// Builds table t from its cell weights: level_width(level) x level_height(level), row-major, sanitised; cells
  /// whose fine node is 0 get 0. Throws Error for a size mismatch or when no cell with light has a positive weight.
  /// Distinct tables may be built concurrently; build each once, before any distribution reads it.
  void build(std::size_t t, std::span<const float> cell_weights);
  std::size_t size() const { return pdf_scale_.size(); }
  /// Bytes per table (a multiple of 64).
  std::size_t table_bytes() const { return stride_ * sizeof(float); }
  int level() const { return level_; }
  const std::shared_ptr<const HierarchicalDistribution2D>& fine() const { return fine_; }

 private:
  friend class RefinedDistribution2D;
  struct Level {
    std::size_t offset = 0;          // in floats from the table's start
    std::size_t blocks_per_row = 0;  // the width of the level above
    int width = 0, height = 0;       // nodes in this level
  };
  const float* table(std::size_t t) const { return base_ + t * stride_; }

  std::shared_ptr<const HierarchicalDistribution2D> fine_;
  int level_ = 0;
  std::vector<Level> levels_;  // index k = level k of the cell pyramid (0: the cells), below its 1 x 1 top
  std::size_t stride_ = 0;     // floats per table, a multiple of 16
  std::vector<float> nodes_;   // the tables, from base_ (its first 64-byte boundary)
  float* base_ = nullptr;
  std::vector<double> pdf_scale_;  // per table: the cell pyramid's pdf factor (HierarchicalDistribution2D::pdf_scale)
};

class RefinedDistribution2D final : public Distribution2D {
 public:
  /// fine: the pyramid to refine with; level: 0 <= level <= fine->levels(); cell_weights: level_width(level) x
  /// level_height(level) weights, row-major (sanitised like every weight). Throws Error for a size mismatch, a
  /// level out of range, or when no cell with light has a positive weight.
  RefinedDistribution2D(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                        std::span<const float> cell_weights);
  /// Table t of a store whose table t is built (RefinedCellStore::build).
  RefinedDistribution2D(std::shared_ptr<const RefinedCellStore> store, std::size_t t);

  const char* method() const override { return "refined"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Refined; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  std::size_t bytes() const override;

  /// sample_texel() as an inline, non-virtual call, for callers that know the class (SphericalDistribution).
  /// The cells' descent is HierarchicalDistribution2D::pick()'s over the same nodes (the same steps on the same
  /// floats), then the fine pyramid's pick_below() from the chosen cell.
  TexelSample pick(Vec2 u) const {
    double ux = sampling::clamp_decision(u.x), uy = sampling::clamp_decision(u.y);
    std::size_t i = 0, j = 0;
    double leaf = 0.0;
    const RefinedCellStore::Level* level = levels_;
    for (int m = top_ - 1; m >= 0; --m)
      leaf = detail::hierarchical_step(cells_ + level[m].offset + (j * level[m].blocks_per_row + i) * 4, ux, uy, i, j);
    const double cell_pdf = leaf * pdf_scale_;
    TexelSample t =
        fine_->pick_below(level_, int(i), int(j), Vec2(std::min(kTexelOffsetMax, ux), std::min(kTexelOffsetMax, uy)));
    t.pdf = density(t.pdf, cell_pdf);
    return t;
  }
  /// pick(u[s]) of d[s] into out[s] for every s < n, bit for bit, sampling::kDrawGroup at a time: the draws of one
  /// shading point,
  /// each from its own table (a mixture's two), their descents interleaved level by level with selects instead of
  /// jumps (detail::hierarchical_step_select), so that the samples' division chains and misses overlap instead of
  /// running one after another behind mispredicted decisions. Tables of one store descend together; others draw
  /// one by one.
  static void pick_group(const RefinedDistribution2D* const* d, const Vec2* u, TexelSample* out, std::size_t n);
  /// Batched sample_texel(), bit for bit: pick_group() over this table.
  void sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const override;
  /// Density w.r.t. uv area of texel (x, y) (0 outside the grid).
  double texel_pdf(int x, int y) const;

 private:
  // What a draw reads first, together.
  const float* cells_ = nullptr;                      // this table's cell pyramid in the store
  const RefinedCellStore::Level* levels_ = nullptr;   // the store's level list
  const HierarchicalDistribution2D* fine_ = nullptr;  // = store_->fine()
  int top_ = 0;                                       // levels of the cell pyramid above the cells
  int level_ = 0;
  double pdf_scale_ = 0.0;  // the cell pyramid's: cell density = leaf x pdf_scale_
  double cell_area_ = 1.0;  // 1 / (cells' width x height): cell probability = cell density x cell_area_
  std::shared_ptr<const RefinedCellStore> store_;
  /// The cell pyramid's stored node of cell (cx, cy) (in the grid of cells).
  float cell(int cx, int cy) const {
    const RefinedCellStore::Level& l = levels_[0];
    return cells_[l.offset + (std::size_t(cy >> 1) * l.blocks_per_row + std::size_t(cx >> 1)) * 4 +
                  std::size_t((cy & 1) * 2 + (cx & 1))];
  }
  /// The density of a texel from its density given its cell (pick_below's pdf) and its cell's density under the
  /// cell pyramid: the one formula of pick() and texel_pdf().
  double density(double given_cell, double cell_pdf) const { return given_cell * (cell_pdf * cell_area_); }
};

}  // namespace envkit
