#include <envkit/maps/solid_angle_table.h>

namespace envkit {

SolidAngleTable::SolidAngleTable(const Parameterization& param) : width_(param.width()) {
  const int W = param.width(), H = param.height();
  if (param.latlong_geometry()) {  // a lat-long's texels share one solid angle per row
    per_row_.resize(H);
    halve_edge_columns_ = param.grid() == TexelGrid::Corner && W > 1;
    for (int j = 0; j < H; ++j) {
      per_row_[j] = halve_edge_columns_ ? 2.0 * param.texel_solid_angle(0, j) : param.texel_solid_angle(0, j);
      total_ += per_row_[j] * (halve_edge_columns_ ? W - 1 : W);
    }
    return;
  }
  if (param.kind() == Kind::Octahedral || param.kind() == Kind::HEALPix) {  // equal-area
    constant_ = param.texel_solid_angle(0, 0);
    total_ = constant_ * W * H;
    return;
  }
  per_texel_.resize(static_cast<std::size_t>(W) * H);
  total_ = param.texel_solid_angles(per_texel_);
}

}  // namespace envkit
