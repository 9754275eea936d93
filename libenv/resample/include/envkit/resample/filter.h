#pragma once
/// @file filter.h
/// Reconstruction of a map's radiance at a continuous image position (the point filters), honouring the
/// parameterization's topology: taps outside the chart are resolved by Parameterization::resolve_tap (longitude
/// wraps, cube edges re-project, octahedral edges fold) and texels without data are dropped with the remaining
/// weights renormalised.
#include <envkit/core/image.h>
#include <envkit/maps/parameterization.h>

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

  /// Filtered value of all channels at p; returns false (and zeros) where there is no data.
  bool sample(Vec2 p, Filter filter, float* out) const;

 private:
  bool resolve(int anchor_i, int anchor_j, int& i, int& j) const;
  const Image& image_;
  const Parameterization& param_;
  std::vector<unsigned char> covered_;  // empty when every texel is covered
};

}  // namespace envkit
