#pragma once
/// @file filter.h
/// Reconstruction of a map's radiance at a continuous image position (the point filters), honouring the
/// parameterization's topology: taps outside the chart are resolved by Parameterization::resolve_tap (longitude
/// wraps, cube edges re-project, octahedral edges fold) and texels without data are dropped with the remaining
/// weights renormalised.
#include <envkit/core/image.h>
#include <envkit/maps/parameterization.h>

#include <cstdint>
#include <string>
#include <vector>

namespace envkit {

enum class Filter {
  Nearest,   ///< the texel containing the point
  Bilinear,  ///< tent over the 2x2 nearest texel centres
  Bicubic,   ///< Catmull-Rom over 4x4 texel centres (interpolating, sharper; negative overshoot is clamped to 0)
  Area,      ///< resampling only: integrate radiance over each output texel's solid angle (flux-conserving)
};

std::string filter_name(Filter filter);
/// "nearest", "bilinear", "bicubic", "area" (also "box"). Throws Error.
Filter parse_filter(const std::string& name);

/// A filter tap: flat texel index (y * width + x) and weight.
struct Tap {
  std::size_t index;
  float weight;
};

/// Read-only view of a map for filtering: the image, its parameterization and which texels hold data.
class TexelSource {
 public:
  TexelSource(const Image& image, const Parameterization& param);

  const Image& image() const { return image_; }
  const Parameterization& param() const { return param_; }
  /// True when every texel holds data (no blank cells, no rim outside a ball) and the map sees the whole sphere
  /// (not a camera view).
  bool fully_covered() const { return covered_.empty() && param_.covers_sphere(); }
  bool covered(std::size_t index) const { return covered_.empty() || covered_[index] != 0; }

  /// Taps of `filter` (Nearest, Bilinear or Bicubic) at position p with weights that sum to 1 over the
  /// covered taps. Returns the number of taps written to `taps` (at most 16), 0 where no covered texel is near.
  int taps(Vec2 p, Filter filter, Tap* taps) const;

  /// Bilinear's common case, which taps() takes first: the 2 x 2 texels around p lie inside the image, on one chart,
  /// and hold data. Writes their four taps and returns true; false (nothing written) otherwise. Inline for loops
  /// that reconstruct every texel of a map.
  bool interior_bilinear_taps(Vec2 p, Tap* out) const {
    const double fx = p.x - 0.5, fy = p.y - 0.5;
    // Truncation is the floor here: both are at least 0 (and NaN fails the test).
    if (!(fx >= 0.0 && fy >= 0.0 && fx < image_.width && fy < image_.height) || !covered_.empty()) return false;
    const int i0 = static_cast<int>(fx), j0 = static_cast<int>(fy), cell = param_.tap_cell();
    // i0 and i0 + 1 lie in one cell unless i0 + 1 is a multiple of its size (likewise j0).
    if (i0 + 1 >= image_.width || j0 + 1 >= image_.height ||
        !(cell == 0 || (cell > 0 && !multiple_of_cell(i0 + 1) && !multiple_of_cell(j0 + 1))))
      return false;
    const float tx = static_cast<float>(fx - i0), ty = static_cast<float>(fy - j0);
    const std::size_t t = static_cast<std::size_t>(j0) * image_.width + i0;
    out[0] = Tap{t, (1 - tx) * (1 - ty)};
    out[1] = Tap{t + 1, tx * (1 - ty)};
    out[2] = Tap{t + image_.width, (1 - tx) * ty};
    out[3] = Tap{t + image_.width + 1, tx * ty};
    return true;
  }

  /// Filtered value of all channels at p; returns false (and zeros) where there is no data.
  bool sample(Vec2 p, Filter filter, float* out) const;

 private:
  bool resolve(int anchor_i, int anchor_j, int& i, int& j) const;
  /// Whether n (0 <= n < 2^31) is a multiple of param_.tap_cell() (> 0), without a division: n * c <= c - 1 in 64-bit
  /// arithmetic, c = ceil(2^64 / cell) (Lemire, Kaser and Kurz, "Faster remainder by direct computation", 2019).
  bool multiple_of_cell(int n) const { return static_cast<std::uint64_t>(n) * cell_multiple_ <= cell_multiple_ - 1; }
  const Image& image_;
  const Parameterization& param_;
  std::uint64_t cell_multiple_ = 0;     // c above, when tap_cell() > 0 (it wraps to 0 for a cell of 1: every n)
  std::vector<unsigned char> covered_;  // empty when every texel is covered
};

}  // namespace envkit
