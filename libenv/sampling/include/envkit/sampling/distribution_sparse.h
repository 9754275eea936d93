#pragma once
/// @file distribution_sparse.h
/// A 2D distribution whose weight lies on a few texels of a large grid (the texels of a sun, see sun_split.h):
/// it stores the lit texels, their cumulative probabilities and their densities, nothing per texel of the grid.
/// O(log n) per sample and per pdf for n lit texels.
///
/// Warp: u.x chooses the texel by its cumulative probability (texels in ascending index order); the fraction of
/// u.x left inside the chosen texel's step is the offset along x, u.y the offset along y. The warp is monotone in
/// u.x, so it is invertible; it keeps the stratification of u.y and, within each texel's step, of u.x.
#include <envkit/sampling/distribution.h>

#include <cstdint>
#include <span>
#include <vector>

namespace envkit {

class SparseDistribution2D final : public StoredDistribution2D {
 public:
  /// texels: indices y * width + x, strictly ascending, inside the grid; weights: one per texel, sanitised like
  /// every weight (distribution.h). Texels whose weight is 0 are dropped. Throws Error for indices that are out of
  /// order or outside the grid, mismatched sizes, or when no weight is positive (a sparse distribution has no
  /// uniform fallback: it would put light where there is none).
  SparseDistribution2D(int width, int height, std::span<const std::uint64_t> texels, std::span<const float> weights);
  /// Restores a distribution written by save(); validates what it reads (Error naming in.context()).
  explicit SparseDistribution2D(BlobReader& in);

  const char* method() const override { return "sparse"; }
  BuiltinDistribution builtin() const override { return BuiltinDistribution::Sparse; }
  DistributionSample sample(Vec2 u) const override;
  TexelSample sample_texel(Vec2 u) const override;
  double pdf(Vec2 uv) const override;
  double texel_probability(int x, int y) const override;
  bool can_invert() const override { return true; }
  Vec2 invert(Vec2 uv) const override;
  std::size_t bytes() const override;
  void save(BlobWriter& out) const override;

  /// The lit texels (indices y * width + x, ascending).
  std::span<const std::uint64_t> texels() const { return texels_; }

 private:
  /// Position of texel (x, y) in texels_, or -1 when it is not lit (or outside the grid).
  std::ptrdiff_t find(int x, int y) const;
  void validate(const std::string& context) const;

  std::vector<std::uint64_t> texels_;
  std::vector<double> cdf_;     ///< texels_.size() + 1 entries from 0 to 1
  std::vector<double> pdf_uv_;  ///< per lit texel: its probability x width x height (density w.r.t. uv area)
};

}  // namespace envkit
