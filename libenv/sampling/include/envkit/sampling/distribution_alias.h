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
///   u.y * H = row candidate (integer part) + f (fraction). Coin: the smaller of the keep share q and the
///   alias share 1 - q comes first in [0,1) (the stored |keep|, t): f < t keeps the candidate when q <= 1/2 and
///   takes the alias when q > 1/2. The coin's own fraction, f / t or (f - t) / (1 - t), is again uniform in [0,1)
///   and becomes the offset of the sample inside the row. u.x does the same with the chosen row's table for the
///   column; its 16-byte bin also holds the alias's weight, so the whole column step reads one bin.
///   Each step re-uniformises and clamps. The cost in bits: log2(H) + log2(W) for the candidates, then the
///   coin's resolution, then whatever is left for the position; with 53-bit u there is plenty (39 bits left at
///   W = 16384), with a 24-bit float u only 10 bits remain for the coin at W = 16384: feed doubles.
/// The warp is discontinuous in u everywhere (scaling by H scatters neighbouring u over unrelated rows), so
/// stratified or low-discrepancy u lose their structure. Not invertible.
#include <envkit/sampling/distribution.h>

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace envkit {

/// One bin of an alias table: 16 bytes, aligned, so a pick reads one entry of one cache line: the coin (keep),
/// the alias and the weight of whichever of the two it chooses.
struct alignas(16) AliasBin {
  float keep = -0.0f;         ///< keep probability q, two-sided: +q (q <= 1/2) or -(1 - q); -0 = always keep
  std::uint32_t alias = 0;    ///< the bin taken otherwise
  float weight = 0.0f;        ///< the sanitised weight (1 under the uniform fallback), for pdf()
  float alias_weight = 0.0f;  ///< weight of bin `alias` (a copy of its `weight`, bit for bit)
};
static_assert(sizeof(AliasBin) == 16);

namespace detail {

/// The coin of one alias step: keep the candidate `bin` or take its alias, with coin uniform in
/// [0, kOneMinusEpsilon]. The smaller of the two shares comes first in [0, 1): with the two-sided keep (see
/// AliasBin::keep) |stored| is that share, q = stored when the sign is clear (keep below it), r = 1 - q = -stored
/// when it is set (alias below it). Either way coin is compared with the stored float itself, which resolves tiny
/// shares exactly (no 1 - r is ever formed). Writes the coin's leftover, again uniform in
/// [0, 1), as the offset inside the chosen bin: coin / t below t, (coin - t) / (1 - t) above it; both are >= +0
/// and never NaN (coin < t implies t > 0, and 1 - t >= 1/2), so the upper bound is the whole of
/// sampling::clamp_offset().
/// +0 ("never keep") and -0 ("always keep") put the whole coin above 0: alias and candidate respectively.
template <class Bin>
[[gnu::always_inline]] inline bool alias_keep(const Bin& bin, double coin, double& offset) {
  const float stored = bin.keep;
  double o;
  bool keep;
  if (!std::signbit(stored)) {  // t = q: the candidate's part first
    const double t = stored;
    if (coin < t) {
      o = coin / t;
      keep = true;
    } else {
      o = (coin - t) / (1.0 - t);
      keep = false;
    }
  } else {  // t = 1 - q: the alias's part first
    const double t = -double(stored);
    if (coin < t) {
      o = coin / t;
      keep = false;
    } else {
      o = (coin - t) / (1.0 - t);
      keep = true;
    }
  }
  offset = o < kTexelOffsetMax ? o : kTexelOffsetMax;
  return keep;
}

/// The candidate of one alias step: u (clamped to [0, kOneMinusEpsilon] by the caller) over n bins. u <= 1 - 2^-53
/// and n <= 2^24 give s = u n < n after rounding (n (1 - 2^-53) is representable for n a power of two, and more
/// than half an ulp below n otherwise), so the candidate needs no upper clamp, and the fraction s - candidate is
/// exact (Sterbenz), in [0, 1 - 2^-53]: the coin needs no clamp either.
[[gnu::always_inline]] inline std::uint32_t alias_candidate(double u, double n, double& coin) {
  const double s = u * n;
  const int candidate = static_cast<int>(s);
  coin = s - candidate;
  return static_cast<std::uint32_t>(candidate);
}

}  // namespace detail

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

/// 2D alias sampling: marginal alias table over rows, one alias table per row. 16 bytes per texel (keep, alias,
/// weight, alias weight: one aligned entry per column pick) + 8 per row. Rows are built in parallel with TBB for
/// large grids; results do not depend on the thread count.
class AliasDistribution2D final : public StoredDistribution2D {
 public:
  /// weights: W x H floats, row-major, row 0 first. Throws Error for a bad size or null weights.
  AliasDistribution2D(const float* weights, int width, int height);
  /// Restores a distribution written by save(); throws Error (naming in.context()) for inconsistent tables.
  explicit AliasDistribution2D(BlobReader& in);
  void save(BlobWriter& out) const override;

  const char* method() const override { return "alias"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Alias; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  /// Batched sample_texel(), bit for bit: see pick_group().
  void sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  std::size_t bytes() const override;

  /// sample_texel() as an inline, non-virtual call, for callers that know the class (SphericalDistribution).
  TexelSample pick(Vec2 u) const;

  /// pick() of n <= sampling::kSampleGroup samples in stages over the whole group, each prefetching what the next
  /// touches: the row candidates' marginal bins, then the chosen rows' column bins (one 16-byte bin of a table of
  /// 16 W H bytes: the miss of this warp), then the coins.
  void pick_group(const Vec2* u, TexelSample* out, std::size_t n) const;

 private:
  /// Throws Error("<context>: invalid alias table (...)") unless the restored values are consistent.
  void validate(const std::string& context) const;
  struct RowBin {
    float keep = -0.0f;  // as AliasBin::keep
    std::uint32_t alias = 0;
  };
  TableArray<AliasBin> texels_;  // H rows of W bins
  TableArray<RowBin> rows_;      // marginal over rows
  double pdf_scale_ = 0.0;       // pdf = weight * pdf_scale_ = W H / sum(weights)
  double width_f_ = 0.0;         // W and H as doubles (the candidate is u x W)
  double height_f_ = 0.0;
};

[[gnu::always_inline]] inline TexelSample AliasDistribution2D::pick(Vec2 u) const {
  TexelSample t;
  // The row (marginal table).
  double coin;
  std::uint32_t y = detail::alias_candidate(sampling::clamp_decision(u.y), height_f_, coin);
  const RowBin& row_bin = rows_[y];
  if (!detail::alias_keep(row_bin, coin, t.fy)) y = row_bin.alias;
  // The column: one 16-byte bin holds the coin, the alias and both weights, so pdf needs no second lookup.
  const std::uint32_t candidate = detail::alias_candidate(sampling::clamp_decision(u.x), width_f_, coin);
  const AliasBin& bin = texels_[std::size_t(y) * std::size_t(width_) + candidate];
  const bool keep = detail::alias_keep(bin, coin, t.fx);
  t.x = static_cast<int>(keep ? candidate : bin.alias);
  t.y = static_cast<int>(y);
  t.pdf = double(keep ? bin.weight : bin.alias_weight) * pdf_scale_;
  return t;
}

}  // namespace envkit
