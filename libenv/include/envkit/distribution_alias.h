#pragma once
/// @file distribution_alias.h
/// Walker/Vose alias tables: O(1) sampling of a discrete distribution, in 1D and in 2D (a marginal table over
/// rows plus one table per row).
///
/// Tables are built with Vose's algorithm in double and store, per bin, the probability q of keeping the
/// candidate bin and the index of its alias. q is stored two-sided in one float: +q when q <= 1/2, -(1 - q) when
/// q > 1/2. A bin's drawn probability is its own q plus the donations 1 - q_j of the bins that alias to it; a
/// plain float q near 1 would carry each donation with an absolute error of 2^-25, and a bright bin collecting
/// thousands of small donations (a slightly brighter texel in a near-uniform row) would be off by up to ~1e-3
/// relative. Two-sided, every keep share and every donation has float relative precision, so the drawn
/// probability is w / sum to ~1e-7 relative. pdf() is w / integral (the weights are kept, as floats, for that);
/// texel_probability() recomputes the drawn probability from the tables.
///
/// How the two uniforms are split (four decisions plus a position from two numbers):
///   u.y * H = row candidate (integer part) + f (fraction). Coin: keep the candidate if f < q_row, else take
///   its alias. The coin's own fraction, f / q or (f - q) / (1 - q), is again uniform in [0,1) and becomes the
///   offset of the sample inside the row. u.x does the same with the chosen row's table for the column.
///   Each step re-uniformises and clamps. The cost in bits: log2(H) + log2(W) for the candidates, then the
///   coin's resolution, then whatever is left for the position; with 53-bit u there is plenty (39 bits left at
///   W = 16384), with a 24-bit float u only 10 bits remain for the coin at W = 16384: feed doubles.
/// The warp is discontinuous in u everywhere (scaling by H scatters neighbouring u over unrelated rows), so
/// stratified or low-discrepancy u lose their structure. Not invertible.
#include <envkit/distribution.h>

#include <cstdint>
#include <span>
#include <vector>

namespace envkit {

/// One bin of an alias table.
struct AliasBin {
  float keep = -0.0f;       ///< keep probability q, two-sided: +q (q <= 1/2) or -(1 - q); -0 = always keep
  std::uint32_t alias = 0;  ///< the bin taken otherwise
  float weight = 0.0f;      ///< the sanitised weight (1 under the uniform fallback), for pdf()
};

/// A piecewise-constant density on [0,1) with n equal bins, sampled in O(1) through an alias table.
class AliasTable1D {
 public:
  struct Sample {
    double x = 0.0;    ///< position in [0,1), strictly inside bin `index`
    double pdf = 0.0;  ///< density w.r.t. length on [0,1)
    int index = 0;
  };

  AliasTable1D() = default;
  /// Weights are sanitised (negative/NaN -> 0, inf -> FLT_MAX); all-zero weights give the uniform density.
  /// Throws Error for an empty span or more than 2^24 bins.
  explicit AliasTable1D(std::span<const float> weights);

  /// u * n picks the candidate, its fraction flips the coin, the coin's leftover places x inside the bin.
  Sample sample(double u) const;
  /// Density at x in [0,1] (1.0 belongs to the last bin); 0 outside and for NaN.
  double pdf(double x) const;
  /// Probability sample() gives bin i, recomputed from the table in O(n).
  double bin_probability(int i) const;

  int size() const { return static_cast<int>(bins_.size()); }
  double integral() const { return integral_; }
  bool used_uniform_fallback() const { return uniform_fallback_; }
  std::size_t bytes() const { return bins_.capacity() * sizeof(AliasBin); }

 private:
  std::vector<AliasBin> bins_;
  double pdf_scale_ = 0.0;  // pdf = weight * pdf_scale_
  double integral_ = 0.0;
  bool uniform_fallback_ = false;
};

/// 2D alias sampling: marginal alias table over rows, one alias table per row. 12 bytes per texel (keep, alias,
/// weight) + 8 per row. Rows are built in parallel with TBB for large grids; results do not depend on the
/// thread count.
class AliasDistribution2D final : public Distribution2D {
 public:
  /// weights: W x H floats, row-major, row 0 first. Throws Error for a bad size or null weights.
  AliasDistribution2D(const float* weights, int width, int height);
  /// Restores a distribution written by save(); throws Error (naming in.context()) for inconsistent tables.
  explicit AliasDistribution2D(BlobReader& in);
  void save(BlobWriter& out) const override;

  const char* method() const override { return "alias"; }
  DistributionSample sample(Vec2 u) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  std::size_t bytes() const override;

 private:
  struct RowBin {
    float keep = -0.0f;  // as AliasBin::keep
    std::uint32_t alias = 0;
  };
  TableArray<AliasBin> texels_;  // H rows of W bins
  TableArray<RowBin> rows_;      // marginal over rows
  double pdf_scale_ = 0.0;        // pdf = weight * pdf_scale_ = W H / sum(weights)
};

}  // namespace envkit
