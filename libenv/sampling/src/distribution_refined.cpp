#include <envkit/core/error.h>
#include <envkit/sampling/distribution_refined.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <string>
#include <vector>

namespace envkit {

namespace {

const HierarchicalDistribution2D& checked(const std::shared_ptr<const HierarchicalDistribution2D>& fine) {
  if (!fine) throw Error("refined distribution: null pyramid");
  return *fine;
}

/// The cell weights with every cell whose fine node is 0 set to 0 (nothing below it could be drawn).
std::vector<float> supported_weights(const HierarchicalDistribution2D& fine, int level,
                                     std::span<const float> weights) {
  const int w = fine.level_width(level), h = fine.level_height(level);
  if (weights.size() != std::size_t(w) * std::size_t(h))
    throw Error("refined distribution: " + std::to_string(weights.size()) + " cell weights for a " + std::to_string(w) +
                "x" + std::to_string(h) + " level");
  std::vector<float> out(weights.size());
  bool any = false;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const std::size_t k = std::size_t(j) * std::size_t(w) + std::size_t(i);
      out[k] = fine.node(level, i, j) > 0.0 ? sampling::sanitize_weight(weights[k]) : 0.0f;
      any = any || out[k] > 0.0f;
    }
  if (!any) throw Error("refined distribution: no cell with light has a positive weight");
  return out;
}

int checked_level(const HierarchicalDistribution2D& fine, int level) {
  if (level < 0 || level > fine.levels())
    throw Error("refined distribution: level " + std::to_string(level) + " outside 0.." +
                std::to_string(fine.levels()));
  return level;
}

}  // namespace

RefinedCellStore::RefinedCellStore(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                                   std::size_t tables)
    : fine_(std::move(fine)), level_(checked_level(checked(fine_), level)) {
  // The cell pyramid's levels as HierarchicalDistribution2D lays them out (ceil-halving to 1 x 1, at least one
  // level above the cells), each level's children array after the one above it.
  const int cw = fine_->level_width(level), ch = fine_->level_height(level);
  levels_.push_back({0, 0, cw, ch});
  while (levels_.size() == 1 || levels_.back().width > 1 || levels_.back().height > 1)
    levels_.push_back({0, 0, (levels_.back().width + 1) / 2, (levels_.back().height + 1) / 2});
  levels_.pop_back();  // the 1 x 1 top is the root sum, not stored
  const int top = int(levels_.size());
  std::size_t offset = 0;
  for (int k = top - 1; k >= 0; --k) {
    const int above_w = (levels_[std::size_t(k)].width + 1) / 2, above_h = (levels_[std::size_t(k)].height + 1) / 2;
    levels_[std::size_t(k)].offset = offset;
    levels_[std::size_t(k)].blocks_per_row = std::size_t(above_w);
    offset += 4 * std::size_t(above_w) * std::size_t(above_h);
  }
  stride_ = (offset + 15) / 16 * 16;
  if (tables > (std::size_t(-1) / sizeof(float) - 16) / stride_) throw Error("refined distribution: too many tables");
  nodes_.assign(tables * stride_ + 16, 0.0f);
  const std::uintptr_t p = reinterpret_cast<std::uintptr_t>(nodes_.data());
  base_ = nodes_.data() + ((64 - p % 64) % 64) / sizeof(float);
  pdf_scale_.assign(tables, 0.0);
}

void RefinedCellStore::build(std::size_t t, std::span<const float> cell_weights) {
  if (t >= size()) throw Error("refined distribution: table " + std::to_string(t) + " of " + std::to_string(size()));
  const std::vector<float> w = supported_weights(*fine_, level_, cell_weights);
  // The pyramid HierarchicalDistribution2D builds over these weights, node for node.
  const HierarchicalDistribution2D cells(w.data(), fine_->level_width(level_), fine_->level_height(level_));
  float* out = base_ + t * stride_;
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    const Level& l = levels_[k];
    const int above_h = (l.height + 1) / 2;
    for (int bj = 0; bj < above_h; ++bj)
      for (std::size_t bi = 0; bi < l.blocks_per_row; ++bi)
        for (int d = 0; d < 4; ++d)
          out[l.offset + (std::size_t(bj) * l.blocks_per_row + bi) * 4 + std::size_t(d)] =
              static_cast<float>(cells.node(int(k), int(2 * bi) + (d & 1), 2 * bj + (d >> 1)));
  }
  pdf_scale_[t] = cells.pdf_scale();
}

RefinedDistribution2D::RefinedDistribution2D(std::shared_ptr<const RefinedCellStore> store, std::size_t t)
    : Distribution2D(checked(store ? store->fine() : nullptr).width(), store->fine()->height()),
      store_(std::move(store)) {
  if (t >= store_->size())
    throw Error("refined distribution: table " + std::to_string(t) + " of " + std::to_string(store_->size()));
  cells_ = store_->table(t);
  levels_ = store_->levels_.data();
  fine_ = store_->fine_.get();
  top_ = int(store_->levels_.size());
  level_ = store_->level_;
  pdf_scale_ = store_->pdf_scale_[t];
  cell_area_ = 1.0 / (double(store_->levels_[0].width) * double(store_->levels_[0].height));
  integral_ = 1.0;  // pdf() is normalised by construction
}

namespace {

std::shared_ptr<const RefinedCellStore> single_table(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                                                     std::span<const float> cell_weights) {
  auto store = std::make_shared<RefinedCellStore>(std::move(fine), level, 1);
  store->build(0, cell_weights);
  return store;
}

}  // namespace

RefinedDistribution2D::RefinedDistribution2D(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                                             std::span<const float> cell_weights)
    : RefinedDistribution2D(single_table(std::move(fine), level, cell_weights), 0) {}

TexelSample RefinedDistribution2D::sample_texel(Vec2 u) const { return pick(u); }

DistributionSample RefinedDistribution2D::sample(Vec2 u) const {
  const TexelSample t = sample_texel(u);
  return DistributionSample{Vec2((t.x + t.fx) / width_, (t.y + t.fy) / height_), t.pdf, t.x, t.y};
}

void RefinedDistribution2D::pick_group(const RefinedDistribution2D* const* d, const Vec2* u, TexelSample* out,
                                       std::size_t n) {
  if (n == 0) return;
  const RefinedDistribution2D& first = *d[0];
  for (std::size_t s = 1; s < n; ++s)
    if (d[s]->store_ != first.store_) {
      for (std::size_t k = 0; k < n; ++k) out[k] = d[k]->pick(u[k]);
      return;
    }
  if (n > sampling::kDrawGroup) {
    sampling::for_each_group(
        n, [&](std::size_t g, std::size_t m) { pick_group(d + g, u + g, out + g, m); }, sampling::kDrawGroup);
    return;
  }
  // pick() of every sample, step for step: the cells' descent (one level of every sample at a time), then the fine
  // pyramid's below the chosen cells.
  constexpr std::size_t G = sampling::kDrawGroup;
  double ux[G], uy[G], leaf[G];
  std::size_t i[G], j[G];
  for (std::size_t s = 0; s < n; ++s) {
    ux[s] = sampling::clamp_decision(u[s].x);
    uy[s] = sampling::clamp_decision(u[s].y);
    i[s] = j[s] = 0;
    leaf[s] = 0.0;
  }
  const RefinedCellStore::Level* level = first.levels_;
  for (int m = first.top_ - 1; m >= 0; --m)
    for (std::size_t s = 0; s < n; ++s)
      leaf[s] = detail::hierarchical_step_select(
          d[s]->cells_ + level[m].offset + (j[s] * level[m].blocks_per_row + i[s]) * 4, ux[s], uy[s], i[s], j[s]);
  TexelSample cell[G];
  for (std::size_t s = 0; s < n; ++s) {
    cell[s].x = int(i[s]);
    cell[s].y = int(j[s]);
    cell[s].fx = std::min(kTexelOffsetMax, ux[s]);
    cell[s].fy = std::min(kTexelOffsetMax, uy[s]);
  }
  first.fine_->pick_below_group(first.level_, cell, out, n);
  for (std::size_t s = 0; s < n; ++s) out[s].pdf = d[s]->density(out[s].pdf, leaf[s] * d[s]->pdf_scale_);
}

void RefinedDistribution2D::sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const {
  const RefinedDistribution2D* self[sampling::kDrawGroup];
  std::fill(std::begin(self), std::end(self), this);
  sampling::for_each_group(
      u.size(), [&](std::size_t g, std::size_t n) { pick_group(self, u.data() + g, out.data() + g, n); },
      sampling::kDrawGroup);
}

double RefinedDistribution2D::texel_pdf(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return 0.0;
  const int cx = x >> level_, cy = y >> level_;
  const double node = fine_->node(level_, cx, cy);
  if (!(node > 0.0)) return 0.0;
  // As pick(): pick_below's density given the cell, then density() with the cell's density.
  const double given_cell = fine_->node(0, x, y) / node * (double(width_) * double(height_));
  const double p = density(given_cell, double(cell(cx, cy)) * pdf_scale_);
  return std::isfinite(p) ? p : 0.0;
}

double RefinedDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  return texel_pdf(sampling::texel_index(uv.x, width_), sampling::texel_index(uv.y, height_));
}

double RefinedDistribution2D::texel_probability(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return 0.0;
  // The cell's probability: the product of the cell pyramid's choices down to it (as
  // HierarchicalDistribution2D::texel_probability), then the fine pyramid's below the cell.
  int cx = x >> level_, cy = y >> level_;
  double p = 1.0;
  for (int k = 0; k < top_; ++k) {
    const RefinedCellStore::Level& l = levels_[k];
    const float* c = cells_ + l.offset + (std::size_t(cy >> 1) * l.blocks_per_row + std::size_t(cx >> 1)) * 4;
    const int dx = cx & 1, dy = cy & 1;
    const double left = double(c[0]) + double(c[2]);
    const double pl = left / (left + (double(c[1]) + double(c[3])));
    const double top = c[dx];
    const double pt = top / (top + double(c[2 + dx]));
    if (!(pl >= 0.0) || !(pt >= 0.0)) return 0.0;  // 0/0: an unreachable zero-sum node
    p *= (dx ? 1.0 - pl : pl) * (dy ? 1.0 - pt : pt);
    cx >>= 1;
    cy >>= 1;
  }
  return p * fine_->texel_probability_below(level_, x, y);
}

std::size_t RefinedDistribution2D::bytes() const { return sizeof(*this) + store_->table_bytes(); }

}  // namespace envkit
