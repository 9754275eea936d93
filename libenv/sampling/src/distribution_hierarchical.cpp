#include <envkit/core/simd/simd_level.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <string>

#include "distribution_hierarchical_simd.h"

namespace envkit {

namespace {

using sampling::clamp_decision;
using sampling::clamp_offset;
using sampling::sanitize_weight;

/// Levels with at least this many nodes are built in parallel (each task writes its own rows of nodes).
constexpr std::size_t kParallelNodes = std::size_t(1) << 14;
/// sample() prefetches a level's candidate blocks when the level holds at least this many floats (256 KiB: larger
/// levels are not expected to stay in L2 between samples; smaller ones would cost the prefetch's instructions for
/// nothing).
constexpr std::size_t kPrefetchNodes = std::size_t(1) << 16;
/// Totals above this are stored scaled down by a power of two, so float node sums cannot overflow.
constexpr double kMaxStoredTotal = 0x1p120;

template <class Body>
void for_rows(int rows, std::size_t nodes, const Body& body) {
  if (nodes >= kParallelNodes)
    tbb::parallel_for(tbb::blocked_range<int>(0, rows, 8), [&](const tbb::blocked_range<int>& r) {
      for (int j = r.begin(); j < r.end(); ++j) body(j);
    });
  else
    for (int j = 0; j < rows; ++j) body(j);
}

/// Probability of the left column pair and, within column dx, of the top child (sample() draws them by comparing
/// u x sum with the left/top sum; the same ratios up to the rounding of that product).
inline double left_share(const float* c) {
  const double left = double(c[0]) + double(c[2]);
  return left / (left + (double(c[1]) + double(c[3])));
}
inline double top_share(const float* c, int dx) {
  const double top = c[dx];
  return top / (top + double(c[2 + dx]));
}

}  // namespace

std::size_t HierarchicalDistribution2D::layout_levels() {
  // Level sizes: ceil-halving down to 1 x 1, with at least one level above the weights.
  levels_.assign(1, {width_, height_, 0});
  while (levels_.size() == 1 || levels_.back().width > 1 || levels_.back().height > 1)
    levels_.push_back({(levels_.back().width + 1) / 2, (levels_.back().height + 1) / 2, 0});
  top_level_ = static_cast<int>(levels_.size()) - 1;
  std::size_t size = 0;
  prefetch_top_ = 0;
  for (int k = 0; k < levels(); ++k) {
    levels_[k].offset = size;
    levels_[k].blocks_per_row = std::size_t(levels_[k + 1].width);
    const std::size_t nodes = 4 * std::size_t(levels_[k + 1].width) * std::size_t(levels_[k + 1].height);
    // Reading level k + 1, sample() prefetches level k's candidate blocks when level k is too big to stay cached.
    if (nodes >= kPrefetchNodes) prefetch_top_ = k + 1;
    size += nodes;
  }
  return size;
}

HierarchicalDistribution2D::HierarchicalDistribution2D(BlobReader& in) : StoredDistribution2D(in) {
  const std::size_t size = layout_levels();
  nodes_ = in.table<float>(size);
  root_ = in.scalar<double>();
  pdf_scale_ = in.scalar<double>();
  in.finish();
  if (!(root_ > 0.0) || !(pdf_scale_ > 0.0)) throw Error(in.context() + ": invalid pyramid root");
  validate(in.context());
}

// A checksum only says the bytes are as written: the nodes must also form a pyramid, or sampling descends into
// NaN shares, zero-sum blocks or texels outside the grid. Every node finite and >= 0, nodes outside a level's grid
// 0, each node the sum of its four children (up to the float rounding of the build), the root the sum of the top
// block and pdf_scale = W H / root. One pass over the nodes (4/3 of the texels), like the checksum.
void HierarchicalDistribution2D::validate(const std::string& context) const {
  const auto refuse = [&](const std::string& what) { throw Error(context + ": invalid pyramid (" + what + ")"); };
  const auto close = [](double stored, double sum) {
    if (stored == 0.0 || sum == 0.0) return stored == sum;  // a zero node has zero children and vice versa
    return std::abs(stored - sum) <= 1e-5 * std::max(stored, sum) + 16.0 * double(FLT_TRUE_MIN);  // denormals
  };
  const int top = levels();
  for (int k = 0; k < top; ++k) {
    const Level& child = levels_[k];
    const Level& parent = levels_[k + 1];
    for (int j = 0; j < parent.height; ++j)
      for (int i = 0; i < parent.width; ++i) {
        const float* c = nodes_.data() + child.offset + (std::size_t(j) * child.blocks_per_row + std::size_t(i)) * 4;
        double sum = 0.0;
        for (int d = 0; d < 4; ++d) {
          const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
          if (!(c[d] >= 0.0f && c[d] <= FLT_MAX)) refuse("node not finite and >= 0 at level " + std::to_string(k));
          if ((x >= child.width || y >= child.height) && c[d] != 0.0f)
            refuse("non-zero node outside the grid at level " + std::to_string(k));
          sum += c[d];
        }
        const double stored =
            k + 1 < top ? double(nodes_[levels_[k + 1].offset +
                                        (std::size_t(j / 2) * levels_[k + 1].blocks_per_row + std::size_t(i / 2)) * 4 +
                                        std::size_t((i & 1) + 2 * (j & 1))])
                        : root_;
        if (!close(stored, sum)) refuse("node is not the sum of its children at level " + std::to_string(k + 1));
      }
  }
  const double expected_scale = double(width_) * double(height_) / root_;
  if (!(std::abs(pdf_scale_ - expected_scale) <= 1e-6 * expected_scale)) refuse("pdf scale does not match the root");
  if (!std::isfinite(integral_)) refuse("integral not finite");
}

void HierarchicalDistribution2D::save(BlobWriter& out) const {
  save_base(out);
  out.array(nodes_);
  out.scalar<double>(root_);
  out.scalar<double>(pdf_scale_);
}

HierarchicalDistribution2D::HierarchicalDistribution2D(const float* weights, int width, int height)
    : StoredDistribution2D(width, height) {
  sampling::require_weights(weights);
  nodes_.assign(layout_levels(), 0.0f);
  const int top = levels();

  const std::size_t W = std::size_t(width);
  const int w1 = levels_[1].width, h1 = levels_[1].height;
  std::vector<double> sums(std::size_t(w1) * std::size_t(h1));

  // Level 0 from leaf values leaf_value(x, y) (sanitised weight, possibly scaled, or 1 for the fallback);
  // level-1 sums in double from the stored floats, so the sums describe exactly what is stored.
  const auto fill_leaves = [&](const auto& leaf_value) {
    for_rows(h1, sums.size(), [&](int j) {
      for (int i = 0; i < w1; ++i) {
        float* c = nodes_.data() + (std::size_t(j) * std::size_t(w1) + std::size_t(i)) * 4;
        double s = 0.0;
        for (int d = 0; d < 4; ++d) {
          const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
          c[d] = (x < width && y < height) ? leaf_value(x, y) : 0.0f;
          s += c[d];
        }
        sums[std::size_t(j) * std::size_t(w1) + std::size_t(i)] = s;
      }
    });
  };
  // Upper levels: node values are the double sums of the level below, rounded to float once each. Consumes
  // `sums`; returns the root, the pairwise double sum of the stored leaves.
  const auto build_upper = [&]() {
    std::vector<double> next;
    for (int k = 1; k < top; ++k) {
      const int cw = levels_[k].width, ch = levels_[k].height;
      const int pw = levels_[k + 1].width, ph = levels_[k + 1].height;
      next.assign(std::size_t(pw) * std::size_t(ph), 0.0);
      for_rows(ph, next.size() * 4, [&](int j) {
        for (int i = 0; i < pw; ++i) {
          float* c = nodes_.data() + levels_[k].offset + (std::size_t(j) * std::size_t(pw) + std::size_t(i)) * 4;
          double s = 0.0;
          for (int d = 0; d < 4; ++d) {
            const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
            const double v = (x < cw && y < ch) ? sums[std::size_t(y) * std::size_t(cw) + std::size_t(x)] : 0.0;
            c[d] = static_cast<float>(v);
            s += v;
          }
          next[std::size_t(j) * std::size_t(pw) + std::size_t(i)] = s;
        }
      });
      sums.swap(next);
    }
    return sums[0];
  };

  fill_leaves([&](int x, int y) { return sanitize_weight(weights[std::size_t(y) * W + std::size_t(x)]); });
  const double total = build_upper();
  integral_ = total / (double(width) * double(height));
  double root = total;
  if (!(total > 0.0)) {
    uniform_fallback_ = true;
    sums.assign(std::size_t(w1) * std::size_t(h1), 0.0);
    fill_leaves([](int, int) { return 1.0f; });
    root = build_upper();
  } else if (total > kMaxStoredTotal) {
    const int shift = std::ilogb(total);  // scaled total in [1, 2): no upper node can overflow
    sums.assign(std::size_t(w1) * std::size_t(h1), 0.0);
    fill_leaves([&](int x, int y) {
      return static_cast<float>(
          std::ldexp(double(sanitize_weight(weights[std::size_t(y) * W + std::size_t(x)])), -shift));
    });
    root = build_upper();
  }
  root_ = root;
  pdf_scale_ = (double(width) * double(height)) / root;
}

DistributionSample HierarchicalDistribution2D::sample(Vec2 u) const {
  const TexelSample t = pick(u);
  DistributionSample s;
  s.uv = Vec2((t.x + t.fx) / width_, (t.y + t.fy) / height_);
  s.pdf = t.pdf;
  s.x = t.x;
  s.y = t.y;
  return s;
}

TexelSample HierarchicalDistribution2D::sample_texel(Vec2 u) const { return pick(u); }

void HierarchicalDistribution2D::sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const {
  sampling::for_each_group(u.size(),
                           [&](std::size_t g, std::size_t n) { pick_group(u.data() + g, out.data() + g, n); });
}

void HierarchicalDistribution2D::pick_group(const Vec2* u, TexelSample* out, std::size_t n) const {
  if (detail::use_avx2() && top_level_ <= detail::HierarchicalWalk::kMaxLevels) {
    detail::HierarchicalWalk walk;
    walk.nodes = nodes_.data();
    for (int k = 0; k < top_level_; ++k) {
      walk.offset[k] = levels_[std::size_t(k)].offset;
      walk.blocks_per_row[k] = levels_[std::size_t(k)].blocks_per_row;
    }
    walk.top = top_level_;
    walk.prefetch_top = prefetch_top_;
    walk.pdf_scale = pdf_scale_;
    if (detail::use_avx512())
      detail::hierarchical_pick_group_avx512(walk, u, out, n);
    else
      detail::hierarchical_pick_group_avx2(walk, u, out, n);
    return;
  }
  constexpr std::size_t G = sampling::kSampleGroup;
  double ux[G], uy[G];
  std::size_t i[G], j[G];
  for (std::size_t s = 0; s < n; ++s) {
    ux[s] = clamp_decision(u[s].x);
    uy[s] = clamp_decision(u[s].y);
    i[s] = j[s] = 0;
  }
  const float* nodes = nodes_.data();
  const Level* level = levels_.data();
  const auto block = [&](int k, std::size_t s) {
    return nodes + level[k].offset + (j[s] * level[k].blocks_per_row + i[s]) * 4;
  };
  int k = top_level_ - 1;
  // Small top levels: cached, no prefetch.
  for (; k > prefetch_top_; --k)
    for (std::size_t s = 0; s < n; ++s) detail::hierarchical_step_select(block(k, s), ux[s], uy[s], i[s], j[s]);
  // Large levels: after a sample's step the block it reads at the next level is known; prefetch it (one line). It
  // is read in the next pass over the group, after the other samples' steps, by when it has arrived. (pick()
  // prefetches both candidate rows before its step instead: there the step itself is all the time there is.)
  for (; k > 0; --k)
    for (std::size_t s = 0; s < n; ++s) {
      detail::hierarchical_step_select(block(k, s), ux[s], uy[s], i[s], j[s]);
      __builtin_prefetch(block(k - 1, s));
    }
  for (std::size_t s = 0; s < n; ++s) {
    const double leaf = detail::hierarchical_step_select(block(0, s), ux[s], uy[s], i[s], j[s]);
    out[s].fx = std::min(kTexelOffsetMax, ux[s]);
    out[s].fy = std::min(kTexelOffsetMax, uy[s]);
    out[s].pdf = leaf * pdf_scale_;
    out[s].x = int(i[s]);
    out[s].y = int(j[s]);
  }
}

void HierarchicalDistribution2D::pick_below_group(int k, const TexelSample* node, TexelSample* out,
                                                  std::size_t n) const {
  constexpr std::size_t G = sampling::kSampleGroup;
  double ux[G], uy[G], top[G];
  std::size_t i[G], j[G];
  for (std::size_t s = 0; s < n; ++s) {
    ux[s] = clamp_decision(node[s].fx);
    uy[s] = clamp_decision(node[s].fy);
    i[s] = std::size_t(node[s].x);
    j[s] = std::size_t(node[s].y);
    top[s] = this->node(k, node[s].x, node[s].y);
  }
  double leaf[G];
  for (std::size_t s = 0; s < n; ++s) leaf[s] = top[s];
  const float* nodes = nodes_.data();
  const Level* level = levels_.data();
  const auto block = [&](int m, std::size_t s) {
    return nodes + level[m].offset + (j[s] * level[m].blocks_per_row + i[s]) * 4;
  };
  // As pick_group(): after a sample's step on a large level, prefetch the block it reads next.
  for (int m = k - 1; m >= 0; --m) {
    const bool prefetch = m > 0 && m <= prefetch_top_;
    for (std::size_t s = 0; s < n; ++s) {
      leaf[s] = detail::hierarchical_step_select(block(m, s), ux[s], uy[s], i[s], j[s]);
      if (prefetch) __builtin_prefetch(block(m - 1, s));
    }
  }
  for (std::size_t s = 0; s < n; ++s) {
    out[s].fx = std::min(kTexelOffsetMax, ux[s]);
    out[s].fy = std::min(kTexelOffsetMax, uy[s]);
    out[s].pdf = top[s] > 0.0 ? leaf[s] / top[s] * (double(width_) * double(height_)) : 0.0;
    out[s].x = int(i[s]);
    out[s].y = int(j[s]);
  }
}

double HierarchicalDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  return texel_pdf(sampling::texel_index(uv.x, width_), sampling::texel_index(uv.y, height_));
}

double HierarchicalDistribution2D::texel_probability(int x, int y) const {
  return texel_probability_below(levels(), x, y);
}

double HierarchicalDistribution2D::texel_probability_below(int level, int x, int y) const {
  if (x < 0 || x >= width_ || y < 0 || y >= height_) return 0.0;
  double p = 1.0;
  for (int k = 0; k < std::min(level, levels()); ++k) {
    const float* c = children(k, x >> 1, y >> 1);
    const int dx = x & 1, dy = y & 1;
    const double pl = left_share(c), pt = top_share(c, dx);
    if (!(pl >= 0.0) || !(pt >= 0.0)) return 0.0;  // 0/0: an unreachable zero-sum node
    p *= (dx ? 1.0 - pl : pl) * (dy ? 1.0 - pt : pt);
    x >>= 1;
    y >>= 1;
  }
  return p;
}

Vec2 HierarchicalDistribution2D::invert(Vec2 uv) const {
  uv = sampling::clamp_uv(uv);
  int x = sampling::texel_index(uv.x, width_), y = sampling::texel_index(uv.y, height_);
  double ux = std::min(uv.x * width_ - x, 1.0), uy = std::min(uv.y * height_ - y, 1.0);
  // Undo the choices from the leaf up, mirroring sample(): u = (left + u' right) / sum or u' left / sum.
  // Zero-sum nodes are never sampled; they get the even split so the answer stays defined.
  const auto undo = [](double u, int d, double first, double second) {
    const double sum = first + second;
    if (!(sum > 0.0)) return 0.5 * (d + u);
    return d == 0 ? u * first / sum : (first + u * second) / sum;
  };
  for (int k = 0; k < levels(); ++k) {
    const float* c = children(k, x >> 1, y >> 1);
    const int dx = x & 1, dy = y & 1;
    uy = undo(uy, dy, c[dx], c[2 + dx]);
    ux = undo(ux, dx, double(c[0]) + double(c[2]), double(c[1]) + double(c[3]));
    x >>= 1;
    y >>= 1;
  }
  return Vec2(clamp_decision(ux), clamp_decision(uy));
}

std::size_t HierarchicalDistribution2D::bytes() const { return nodes_.bytes() + levels_.capacity() * sizeof(Level); }

}  // namespace envkit
