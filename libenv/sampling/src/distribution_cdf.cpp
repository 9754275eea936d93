#include <envkit/core/simd/simd_level.h>
#include <envkit/sampling/distribution_cdf.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "distribution_cdf_simd.h"

namespace envkit {

namespace {

using sampling::clamp_decision;
using sampling::clamp_offset;
using sampling::sanitize_weight;

/// Grids with at least this many texels build their rows in parallel.
constexpr std::size_t kParallelTexels = std::size_t(1) << 16;

using detail::TwoSidedCdf;

struct CdfBuild {
  double sum = 0.0;  // sum of the (sanitised) weights, double
  int split = 0;
  bool uniform = false;         // all weights were zero: uniform bins instead
  std::size_t unreachable = 0;  // positive-weight bins that got a zero step
  std::size_t positive = 0;     // positive-weight bins
};

/// Builds the two-sided CDF of n bins with weights weight(i) (double, >= 0) into t[0..n].
template <class WeightFn>
CdfBuild build_two_sided(int n, const WeightFn& weight, float* t) {
  CdfBuild b;
  for (int i = 0; i < n; ++i) {
    const double w = weight(i);
    b.sum += w;
    b.positive += w > 0.0;
  }
  b.uniform = !(b.sum > 0.0);
  const auto w_at = [&](int i) { return b.uniform ? 1.0 : weight(i); };
  const double total = b.uniform ? double(n) : b.sum;
  const double half = 0.5 * total, inv_total = 1.0 / total;  // a multiply is monotone too, and cheaper

  // Forward part: cumulative mass while it stays <= half of the total.
  double prefix = 0.0;
  int i = 0;
  for (; i <= n; ++i) {
    if (prefix > half) break;
    t[i] = static_cast<float>(prefix * inv_total);
    if (i < n) prefix += w_at(i);
  }
  b.split = i;  // >= 1 since t[0] = 0; <= n since the full prefix exceeds half of a positive total
  // Backward part: remaining mass accumulated from the end, so it keeps full relative precision near 1.
  double suffix = 0.0;
  t[n] = 0.0f;
  for (int j = n - 1; j >= b.split; --j) {
    suffix += w_at(j);
    t[j] = static_cast<float>(suffix * inv_total);
  }
  // Keep the junction monotone (lower(split) >= lower(split - 1)) if both halves rounded towards each other.
  // (Only possible when the junction bin is at the rounding level; the loop keeps later entries monotone too.)
  while (1.0 - double(t[b.split]) < double(t[b.split - 1])) t[b.split] = std::nextafter(t[b.split], 0.0f);
  for (int j = b.split + 1; j <= n && t[j] > t[j - 1]; ++j) t[j] = t[j - 1];

  if (!b.uniform) {
    const TwoSidedCdf view{t, n, b.split};
    for (int j = 0; j < n; ++j) b.unreachable += (weight(j) > 0.0 && !(view.step(j) > 0.0));
  }
  return b;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// PiecewiseConstant1D

PiecewiseConstant1D::PiecewiseConstant1D(std::span<const float> weights) {
  if (weights.empty() || weights.size() > std::size_t(kMaxDistributionSize))
    throw Error("PiecewiseConstant1D: need 1.." + std::to_string(kMaxDistributionSize) + " weights, got " +
                std::to_string(weights.size()));
  n_ = static_cast<int>(weights.size());
  cdf_.resize(std::size_t(n_) + 1);
  const CdfBuild b = build_two_sided(
      n_, [&](int i) { return double(sanitize_weight(weights[std::size_t(i)])); }, cdf_.data());
  split_ = b.split;
  integral_ = b.sum / n_;
  uniform_fallback_ = b.uniform;
}

PiecewiseConstant1D::Sample PiecewiseConstant1D::sample(double u) const {
  const TwoSidedCdf view{cdf_.data(), n_, split_};
  double fraction, step;
  const int i = view.find(clamp_decision(u), fraction, step);
  return {(i + clamp_offset(fraction)) / n_, step * n_, i};
}

double PiecewiseConstant1D::pdf(double x) const {
  if (!(x >= 0.0 && x <= 1.0)) return 0.0;
  return bin_probability(sampling::texel_index(x, n_)) * n_;
}

double PiecewiseConstant1D::invert(double x) const {
  x = x > 0.0 ? std::min(x, 1.0) : 0.0;
  const int i = sampling::texel_index(x, n_);
  const TwoSidedCdf view{cdf_.data(), n_, split_};
  return clamp_decision(view.invert(i, x * n_ - i));
}

double PiecewiseConstant1D::bin_probability(int i) const {
  if (i < 0 || i >= n_) return 0.0;
  return TwoSidedCdf{cdf_.data(), n_, split_}.step(i);
}

// ---------------------------------------------------------------------------------------------------------------
// CdfDistribution2D

CdfDistribution2D::CdfDistribution2D(const float* weights, int width, int height)
    : StoredDistribution2D(width, height) {
  sampling::require_weights(weights);
  const std::size_t W = std::size_t(width), H = std::size_t(height), stride = W + 1;
  conditional_.resize(stride * H);
  row_split_.resize(H);
  std::vector<double> row_sum(H);
  std::vector<std::size_t> row_positive(H), row_unreachable(H);
  std::vector<char> row_uniform(H);

  const auto build_rows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* row = weights + std::size_t(y) * W;
      const CdfBuild b = build_two_sided(
          width, [row](int x) { return double(sanitize_weight(row[x])); }, conditional_.data() + stride * y);
      row_split_[y] = b.split;
      row_sum[y] = b.sum;
      row_positive[y] = b.positive;
      row_unreachable[y] = b.unreachable;
      row_uniform[y] = b.uniform;
    }
  };
  if (W * H >= kParallelTexels)
    tbb::parallel_for(tbb::blocked_range<int>(0, height, 16),
                      [&](const tbb::blocked_range<int>& r) { build_rows(r.begin(), r.end()); });
  else
    build_rows(0, height);

  marginal_.resize(H + 1);
  const CdfBuild m = build_two_sided(
      height, [&](int y) { return row_sum[y]; }, marginal_.data());
  marginal_split_ = m.split;

  // Sequential, fixed-order reductions: identical whatever the thread count.
  integral_ = m.sum / (double(W) * double(H));
  uniform_fallback_ = m.uniform;
  const TwoSidedCdf marginal{marginal_.data(), height, marginal_split_};
  for (int y = 0; y < height; ++y) {
    fallback_rows_ += row_uniform[y] != 0;
    // A row whose marginal step rounded to zero loses all its texels; otherwise only its zero-step bins.
    unreachable_texels_ += (m.uniform || marginal.step(y) > 0.0) ? row_unreachable[y] : row_positive[y];
  }
}

CdfDistribution2D::CdfDistribution2D(BlobReader& in) : StoredDistribution2D(in) {
  const std::size_t W = std::size_t(width_), H = std::size_t(height_);
  conditional_ = in.table<float>((W + 1) * H);
  row_split_ = in.table<std::int32_t>(H);
  marginal_ = in.table<float>(H + 1);
  marginal_split_ = in.scalar<std::int32_t>();
  in.finish();
  // Read through const views: the non-const accessors address the (empty) owned storage of a building table.
  const TableArray<float>& conditional = conditional_;
  const TableArray<std::int32_t>& row_split = row_split_;
  const TableArray<float>& marginal = marginal_;
  // Entry 0 (cdf 0) is always stored forward, so a built table has split >= 1; the search relies on it.
  const auto valid_split = [](std::int32_t split, std::size_t n) { return split >= 1 && std::size_t(split) <= n; };
  if (!valid_split(marginal_split_, H) ||
      !std::all_of(row_split.begin(), row_split.end(), [&](std::int32_t s) { return valid_split(s, W); }))
    throw Error(in.context() + ": CDF split index out of range");
  // A checksum only says the bytes are as written, not that they form a CDF: every table must start at 0, rise
  // (forward part) and fall (backward part) in [0, 1], and end at 0, so every bin probability is finite and >= 0
  // and sums to 1. And the split must be where a build puts it, with at most half the mass behind it: the search
  // sends every u < 1/2 to the forward part, and only then is the bin it lands in never a zero-step bin (a forward
  // part holding less than half would send some u past its last entry, into the junction bin, whatever its step).
  // One pass over the entries, like the checksum.
  const auto valid_cdf = [](const float* t, int n, int split) {
    if (t[0] != 0.0f || t[n] != 0.0f || !(double(t[split]) <= 0.5)) return false;
    for (int i = 0; i <= n; ++i)
      if (!(t[i] >= 0.0f && t[i] <= 1.0f)) return false;
    for (int i = 1; i < split; ++i)
      if (t[i] < t[i - 1]) return false;
    for (int i = split + 1; i <= n; ++i)
      if (t[i] > t[i - 1]) return false;
    return detail::TwoSidedCdf{t, n, split}.step(split - 1) >= 0.0;  // the junction bin
  };
  if (!valid_cdf(marginal.data(), height_, marginal_split_))
    throw Error(in.context() + ": invalid marginal CDF (not a non-decreasing CDF from 0 to 1)");
  for (std::size_t y = 0; y < H; ++y)
    if (!valid_cdf(conditional.data() + y * (W + 1), width_, row_split[y]))
      throw Error(in.context() + ": invalid CDF of row " + std::to_string(y) +
                  " (not a non-decreasing CDF from 0 to 1)");
  if (!std::isfinite(integral_)) throw Error(in.context() + ": invalid distribution integral");
}

void CdfDistribution2D::save(BlobWriter& out) const {
  save_base(out);
  out.array(conditional_);
  out.array(row_split_);
  out.array(marginal_);
  out.scalar<std::int32_t>(marginal_split_);
}

DistributionSample CdfDistribution2D::sample(Vec2 u) const {
  const TexelSample t = pick(u);
  DistributionSample s;
  s.uv = Vec2((t.x + t.fx) / width_, (t.y + t.fy) / height_);
  s.pdf = t.pdf;
  s.x = t.x;
  s.y = t.y;
  return s;
}

TexelSample CdfDistribution2D::sample_texel(Vec2 u) const { return pick(u); }

namespace {

/// TwoSidedCdf::find() of n <= sampling::kSampleGroup searches at once, search k in cdf[k] for u[k] (the caller has
/// prefetched each cdf[k].t[split], which decides the part to search). Each round takes one halving step of every
/// search and prefetches its next probe, so the group's probe misses overlap; the steps are those of libstdc++'s
/// std::upper_bound / std::partition_point in find(), so each search reads the same probes and ends in the same
/// bin, bit for bit. On CPUs with AVX-512 (AVX2) the whole search runs eight (four) lanes per vector with masks
/// (distribution_cdf_simd.h). The portable steps are conditional jumps, not selects: on peaky maps most searches
/// take the same path, which the CPU predicts (a scalar select version measured slower on the sun map).
void find_group(const TwoSidedCdf* cdf, const double* u, std::size_t n, int* bin, double* fraction, double* step) {
  constexpr std::size_t G = sampling::kSampleGroup;
  if (n == 0) return;
  if (detail::use_avx2()) {
    // The same steps eight (four) searches per vector, with masks instead of jumps. A group's searches all lie in
    // one table (the marginal, or the rows of the conditional array), addressed from the first one's start.
    std::int64_t start[G];
    int bins[G], split[G];
    for (std::size_t k = 0; k < n; ++k) {
      start[k] = cdf[k].t - cdf[0].t;
      bins[k] = cdf[k].n;
      split[k] = cdf[k].split;
    }
    const auto search = detail::use_avx512() ? detail::cdf_find_group_avx512 : detail::cdf_find_group_avx2;
    search(cdf[0].t, start, bins, split, u, n, bin, fraction, step);
    return;
  }
  double r[G];
  int first[G], len[G];
  bool forward[G];
  for (std::size_t k = 0; k < n; ++k) {
    r[k] = 1.0 - u[k];
    forward[k] = cdf[k].forward(u[k], r[k]);
    first[k] = forward[k] ? 0 : cdf[k].split;
    len[k] = forward[k] ? cdf[k].split : cdf[k].n - cdf[k].split;
    __builtin_prefetch(cdf[k].t + first[k] + (len[k] >> 1));
  }
  for (bool more = true; more;) {
    more = false;
    for (std::size_t k = 0; k < n; ++k) {
      if (len[k] <= 0) continue;
      const int half = len[k] >> 1, middle = first[k] + half;
      if (TwoSidedCdf::after(forward[k], cdf[k].t[middle], u[k], r[k])) {
        first[k] = middle + 1;
        len[k] -= half + 1;
      } else {
        len[k] = half;
      }
      __builtin_prefetch(cdf[k].t + first[k] + (len[k] >> 1));
      more |= len[k] > 0;
    }
  }
  for (std::size_t k = 0; k < n; ++k)
    bin[k] = cdf[k].finish(first[k] - 1, forward[k], u[k], r[k], fraction[k], step[k]);
}

}  // namespace

void CdfDistribution2D::sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const {
  // Rows that stay in a core's L2 have no misses to overlap, and there the group search's bookkeeping costs more
  // than it saves: pick() per sample (the same results).
  // (With AVX-512 or AVX2 the group search has no conditional jumps to mispredict and wins at every size.)
  constexpr std::size_t kCachedBytes = std::size_t(1) << 20;
  if (conditional_.bytes() < kCachedBytes && !detail::use_avx2()) {
    for (std::size_t k = 0; k < u.size(); ++k) out[k] = pick(u[k]);
    return;
  }
  sampling::for_each_group(u.size(),
                           [&](std::size_t g, std::size_t n) { pick_group(u.data() + g, out.data() + g, n); });
}

void CdfDistribution2D::pick_group(const Vec2* u, TexelSample* out, std::size_t n) const {
  constexpr std::size_t G = sampling::kSampleGroup;
  TwoSidedCdf cdf[G] = {};  // (initialised: GCC cannot see that the first n are written)
  double v[G] = {}, fraction[G], step_y[G], step_x[G];
  int y[G], x[G];
  // Rows: the marginal searches, as pick() (H + 1 floats: cached, nothing to overlap; the vector search still saves
  // the mispredicted conditional jumps).
  const TwoSidedCdf marginal{marginal_.data(), height_, marginal_split_};
  if (detail::use_avx2()) {
    for (std::size_t k = 0; k < n; ++k) {
      cdf[k] = marginal;
      v[k] = clamp_decision(u[k].y);
    }
    find_group(cdf, v, n, y, fraction, step_y);
  } else {
    for (std::size_t k = 0; k < n; ++k) y[k] = marginal.find(clamp_decision(u[k].y), fraction[k], step_y[k]);
  }
  // Columns: the chosen rows' searches (a row of W + 1 floats in a table of 4 W H bytes: the misses of this warp);
  // prefetch the entry at each row's split first.
  for (std::size_t k = 0; k < n; ++k) {
    out[k].y = y[k];
    out[k].fy = clamp_offset(fraction[k]);
    cdf[k] = TwoSidedCdf{conditional_.data() + std::size_t(y[k]) * (std::size_t(width_) + 1), width_, row_split_[y[k]]};
    __builtin_prefetch(cdf[k].t + cdf[k].split);
    v[k] = clamp_decision(u[k].x);
  }
  find_group(cdf, v, n, x, fraction, step_x);
  for (std::size_t k = 0; k < n; ++k) {
    out[k].x = x[k];
    out[k].fx = clamp_offset(fraction[k]);
    out[k].pdf = (step_y[k] * height_) * (step_x[k] * width_);
  }
}

double CdfDistribution2D::texel_probability(int x, int y) const {
  if (x < 0 || x >= width_ || y < 0 || y >= height_) return 0.0;
  const TwoSidedCdf marginal{marginal_.data(), height_, marginal_split_};
  const TwoSidedCdf row{conditional_.data() + std::size_t(y) * (std::size_t(width_) + 1), width_, row_split_[y]};
  return marginal.step(y) * row.step(x);
}

double CdfDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  const int x = sampling::texel_index(uv.x, width_);
  const int y = sampling::texel_index(uv.y, height_);
  // Same expression as in sample(), so pdf(sample(u).uv) == sample(u).pdf bit for bit.
  const TwoSidedCdf marginal{marginal_.data(), height_, marginal_split_};
  const TwoSidedCdf row{conditional_.data() + std::size_t(y) * (std::size_t(width_) + 1), width_, row_split_[y]};
  return (marginal.step(y) * height_) * (row.step(x) * width_);
}

Vec2 CdfDistribution2D::invert(Vec2 uv) const {
  uv = sampling::clamp_uv(uv);
  const int x = sampling::texel_index(uv.x, width_);
  const int y = sampling::texel_index(uv.y, height_);
  const TwoSidedCdf marginal{marginal_.data(), height_, marginal_split_};
  const TwoSidedCdf row{conditional_.data() + std::size_t(y) * (std::size_t(width_) + 1), width_, row_split_[y]};
  return Vec2(clamp_decision(row.invert(x, uv.x * width_ - x)), clamp_decision(marginal.invert(y, uv.y * height_ - y)));
}

std::size_t CdfDistribution2D::bytes() const { return conditional_.bytes() + row_split_.bytes() + marginal_.bytes(); }

}  // namespace envkit
