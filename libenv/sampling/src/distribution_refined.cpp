#include <envkit/core/error.h>
#include <envkit/sampling/distribution_refined.h>

#include <cmath>
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
  if (level < 0 || level > fine.levels())
    throw Error("refined distribution: level " + std::to_string(level) + " outside 0.." +
                std::to_string(fine.levels()));
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

/// The coarse distribution over the nodes of `level` (supported_weights).
HierarchicalDistribution2D cell_distribution(const HierarchicalDistribution2D& fine, int level,
                                             std::span<const float> weights) {
  const std::vector<float> w = supported_weights(fine, level, weights);
  return HierarchicalDistribution2D(w.data(), fine.level_width(level), fine.level_height(level));
}

}  // namespace

RefinedDistribution2D::RefinedDistribution2D(std::shared_ptr<const HierarchicalDistribution2D> fine, int level,
                                             std::span<const float> cell_weights)
    : Distribution2D(checked(fine).width(), checked(fine).height()),
      fine_(std::move(fine)),
      level_(level),
      cells_(cell_distribution(*fine_, level, cell_weights)) {
  cell_area_ = 1.0 / (double(cells_.width()) * double(cells_.height()));
  integral_ = 1.0;  // pdf() is normalised by construction
}

TexelSample RefinedDistribution2D::sample_texel(Vec2 u) const { return pick(u); }

DistributionSample RefinedDistribution2D::sample(Vec2 u) const {
  const TexelSample t = sample_texel(u);
  return DistributionSample{Vec2((t.x + t.fx) / width_, (t.y + t.fy) / height_), t.pdf, t.x, t.y};
}

double RefinedDistribution2D::texel_pdf(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return 0.0;
  const int cx = x >> level_, cy = y >> level_;
  const double node = fine_->node(level_, cx, cy);
  if (!(node > 0.0)) return 0.0;
  // As pick(): pick_below's density given the cell, then density().
  const double given_cell = fine_->node(0, x, y) / node * (double(width_) * double(height_));
  const double p = density(given_cell, cells_.texel_pdf(cx, cy));
  return std::isfinite(p) ? p : 0.0;
}

double RefinedDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  return texel_pdf(sampling::texel_index(uv.x, width_), sampling::texel_index(uv.y, height_));
}

double RefinedDistribution2D::texel_probability(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return 0.0;
  return cells_.texel_probability(x >> level_, y >> level_) * fine_->texel_probability_below(level_, x, y);
}

std::size_t RefinedDistribution2D::bytes() const { return sizeof(*this) + cells_.bytes(); }

}  // namespace envkit
