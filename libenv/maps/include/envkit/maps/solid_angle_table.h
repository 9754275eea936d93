#pragma once
/// @file solid_angle_table.h
/// Every texel's exact solid angle, computed once (in parallel) and stored compactly: one value per row for
/// lat-long and sky lat-long maps (a row's texels are equal, except that corner grids halve the duplicated edge
/// columns), one
/// constant for the equal-area maps (octahedral, HEALPix), one float per texel otherwise (relative precision 6e-8,
/// ample for weights).
#include <envkit/maps/parameterization.h>

#include <vector>

namespace envkit {

class SolidAngleTable {
 public:
  explicit SolidAngleTable(const Parameterization& param);

  /// Solid angle of texel (i, j) in steradians.
  double operator()(int i, int j) const {
    if (!per_texel_.empty()) return per_texel_[static_cast<std::size_t>(j) * width_ + i];
    if (!per_row_.empty()) return per_row_[j] * ((i == 0 || i == width_ - 1) && halve_edge_columns_ ? 0.5 : 1.0);
    return constant_;
  }
  /// Sum over all texels (double accumulation): 4 pi for maps that cover the sphere.
  double total() const { return total_; }

 private:
  int width_ = 0;
  bool halve_edge_columns_ = false;
  double constant_ = 0.0;
  std::vector<double> per_row_;
  std::vector<float> per_texel_;
  double total_ = 0.0;
};

}  // namespace envkit
