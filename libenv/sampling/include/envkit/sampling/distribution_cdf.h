#pragma once
/// @file distribution_cdf.h
/// Piecewise-constant distributions sampled by CDF inversion: 1D, and 2D as a marginal over rows times a
/// conditional per row (the classic lat-long environment sampler).
///
/// Two-sided float CDF
/// -------------------
/// Each CDF is accumulated in double and stored in float, but not as plain cdf[i] values: an entry whose
/// cumulative mass is at most 1/2 is stored as cdf[i], an entry past the half-way point as 1 - cdf[i] (the mass
/// still to come, accumulated backwards in double). A float's resolution is relative to its magnitude, so each
/// bin's step is resolved relative to the SMALLER of the masses before and after it. With a plain float CDF every
/// bin after a sun sits where the CDF is ~1 and ulp = 2^-24: the sky texels of a sun row (1e-9 of the row each)
/// get steps of 0 or 6e-8, i.e. are never sampled or 60x oversampled. Two-sided, they are resolved to ~1e-6
/// relative. The last entry is exactly 1 (stored as 0 remaining mass), the first exactly 0.
/// What remains: a bin below ~2^-24 of BOTH the mass before and after it (a dim texel between two suns of one
/// row) can still round to a zero step; unreachable_texels() counts those. The pyramid has no such limit.
///
/// pdf() is computed from the stored steps (not from the weights), so pdf() is exactly the density sample()
/// draws: consistent for MIS and chi-square even where rounding moved a bin's probability. Each stored entry is
/// at most 1/2, so each step is within 2^-24 of its ideal value (less near the ends): a texel of marginal m and
/// conditional c is drawn within (m + c) 2^-24 of m c. That is ~1e-7 relative on small maps but up to ~5e-4 for
/// texels in the middle of a 16k row (n/2 equal bins of 2/n each share the rounding), and more for texels far
/// dimmer than their row. texel_probability() gives the step product for diagnostics. Where per-texel relative
/// accuracy matters, use the pyramid.
///
/// Sampling uses u.y for the row (marginal) and u.x for the column (conditional of that row); inside the chosen
/// bin the position is linear in u (continuous inversion), so invert() is exact.
#include <envkit/sampling/distribution.h>

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

namespace envkit {

namespace detail {

/// Read-only view of a two-sided CDF of n bins: t[0..n], entries below `split` hold cdf[i], entries from `split`
/// on hold 1 - cdf[i] (see distribution_cdf.h). Bin i is [lower(i), lower(i+1)) in u.
struct TwoSidedCdf {
  const float* t;
  int n;
  int split;

  /// Bin probability, computed in double from the two stored floats (exact except at the junction bin, where
  /// 1 - t may round by 2^-53).
  double step(int i) const {
    if (i + 1 < split) return double(t[i + 1]) - double(t[i]);
    if (i >= split) return double(t[i]) - double(t[i + 1]);
    return (1.0 - double(t[i + 1])) - double(t[i]);
  }

  /// u at the start of bin i.
  double lower(int i) const { return i < split ? double(t[i]) : 1.0 - double(t[i]); }

  /// Which part holds the bin of u (u in [0, kOneMinusEpsilon], r = 1 - u): the forward part t[0..split) when
  /// u < 1/2 or the remaining mass at the split is below r, else the backward part t[split..n).
  /// (For u >= 1/2, r = 1 - u is exact (Sterbenz), so comparisons with the stored remaining mass are exact too.)
  bool forward(double u, double r) const { return u < 0.5 || double(t[split]) < r; }

  /// The search's predicate at entry e: true when the bin of u lies after e. Forward part: the last entry <= u
  /// (t[0] = 0 <= u); backward part (t decreases): the last entry with remaining mass >= r (t[n] = 0 < r).
  static bool after(bool forward_part, float e, double u, double r) {
    return forward_part ? !(u < double(e)) : double(e) >= r;
  }

  /// The bin i found by the search: its step and the fraction of the bin before u.
  int finish(int i, bool forward_part, double u, double r, double& fraction, double& bin_step) const {
    bin_step = step(i);
    fraction = forward_part ? (u - double(t[i])) / bin_step : (double(t[i]) - r) / bin_step;
    return i;
  }

  /// The bin containing u (u in [0, kOneMinusEpsilon]) and the fraction of the bin before u. Never returns a
  /// zero-step bin: with lower(i) <= u < lower(i+1) the step is positive.
  int find(double u, double& fraction, double& bin_step) const {
    const double r = 1.0 - u;
    const bool f = forward(u, r);
    // std::upper_bound, not a search by selects: its conditional jumps let the CPU speculate into the next probe.
    const float* p = f ? std::upper_bound(t, t + split, u, [](double v, float e) { return v < double(e); })
                       : std::partition_point(t + split, t + n, [r](float e) { return double(e) >= r; });
    return finish(static_cast<int>(p - t) - 1, f, u, r, fraction, bin_step);
  }

  /// The u at fraction f of bin i.
  double invert(int i, double f) const {
    const double s = step(i);
    return i < split ? double(t[i]) + f * s : 1.0 - (double(t[i]) - f * s);
  }
};

}  // namespace detail

/// A piecewise-constant density on [0,1) with n equal bins, bin i = [i/n, (i+1)/n) with weight w[i].
class PiecewiseConstant1D {
 public:
  struct Sample {
    double x = 0.0;    ///< position in [0,1), strictly inside bin `index`
    double pdf = 0.0;  ///< density w.r.t. length on [0,1)
    int index = 0;     ///< the bin
  };

  PiecewiseConstant1D() = default;
  /// Weights are sanitised (negative/NaN -> 0, inf -> FLT_MAX). All-zero weights give the uniform density
  /// (used_uniform_fallback()). Throws Error for an empty span or more than 2^24 bins.
  explicit PiecewiseConstant1D(std::span<const float> weights);

  Sample sample(double u) const;
  /// Density at x in [0,1] (1.0 belongs to the last bin); 0 outside and for NaN.
  double pdf(double x) const;
  /// Inverse of sample(): the u that maps to x (x clamped to [0,1]).
  double invert(double x) const;
  /// Probability of bin i as stored (the CDF step); 0 outside.
  double bin_probability(int i) const;

  int size() const { return n_; }
  /// sum(w) / n in double (the normaliser); 0 for all-zero weights.
  double integral() const { return integral_; }
  bool used_uniform_fallback() const { return uniform_fallback_; }
  std::size_t bytes() const { return cdf_.capacity() * sizeof(float); }

 private:
  std::vector<float> cdf_;  // n + 1 two-sided entries
  int n_ = 0;
  int split_ = 0;  // first entry stored as remaining mass
  double integral_ = 0.0;
  bool uniform_fallback_ = false;
};

/// Marginal/conditional CDF inversion over a W x H grid (see the file comment). ~4 bytes per texel.
class CdfDistribution2D final : public StoredDistribution2D {
 public:
  /// weights: W x H floats, row-major, row 0 first. Rows are built in parallel with TBB for large grids; the
  /// result does not depend on the thread count. Throws Error for a bad size or null weights.
  CdfDistribution2D(const float* weights, int width, int height);
  /// Restores a distribution written by save(); throws Error (naming in.context()) for inconsistent sizes.
  explicit CdfDistribution2D(BlobReader& in);
  void save(BlobWriter& out) const override;

  const char* method() const override { return "cdf"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Cdf; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  /// Batched sample_texel(), bit for bit: see pick_group().
  void sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  bool can_invert() const override { return true; }
  Vec2 invert(Vec2 uv) const override;
  std::size_t bytes() const override;

  /// sample_texel() as an inline, non-virtual call, for callers that know the class (SphericalDistribution).
  TexelSample pick(Vec2 u) const;

  /// pick() of n <= sampling::kSampleGroup samples in stages over the whole group: the marginal searches (a table of
  /// H floats, cached), then the conditional rows' binary searches run one probe per sample and round, prefetching
  /// each sample's next probe, so that the group's misses in the rows overlap. The probes are those of pick()'s
  /// std::upper_bound / std::partition_point (libstdc++'s halving), so the result is the same bit for bit.
  void pick_group(const Vec2* u, TexelSample* out, std::size_t n) const;

 private:
  TableArray<float> conditional_;       // H rows of W + 1 two-sided entries
  TableArray<std::int32_t> row_split_;  // per row: first entry stored as remaining mass
  TableArray<float> marginal_;          // H + 1 two-sided entries
  int marginal_split_ = 0;
};

[[gnu::always_inline]] inline TexelSample CdfDistribution2D::pick(Vec2 u) const {
  const detail::TwoSidedCdf marginal{marginal_.data(), height_, marginal_split_};
  double fy, step_y;
  const int y = marginal.find(sampling::clamp_decision(u.y), fy, step_y);
  const detail::TwoSidedCdf row{conditional_.data() + std::size_t(y) * (std::size_t(width_) + 1), width_,
                                row_split_[y]};
  double fx, step_x;
  const int x = row.find(sampling::clamp_decision(u.x), fx, step_x);
  TexelSample t;
  t.fx = sampling::clamp_offset(fx);
  t.fy = sampling::clamp_offset(fy);
  t.pdf = (step_y * height_) * (step_x * width_);
  t.x = x;
  t.y = y;
  return t;
}

}  // namespace envkit
