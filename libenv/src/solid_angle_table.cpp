#include <envkit/latlong.h>
#include <envkit/solid_angle_table.h>

#include <tbb/parallel_for.h>

namespace envkit {

SolidAngleTable::SolidAngleTable(const Parameterization& param) : width_(param.width()) {
  const int W = param.width(), H = param.height();
  if (const auto* ll = dynamic_cast<const LatLongMap*>(&param)) {
    per_row_.resize(H);
    halve_edge_columns_ = ll->grid() == TexelGrid::Corner && W > 1;
    for (int j = 0; j < H; ++j) {
      per_row_[j] = halve_edge_columns_ ? 2.0 * param.texel_solid_angle(0, j) : param.texel_solid_angle(0, j);
      total_ += per_row_[j] * (halve_edge_columns_ ? W - 1 : W);
    }
    return;
  }
  if (param.kind() == Kind::Octahedral) {
    constant_ = param.texel_solid_angle(0, 0);
    total_ = constant_ * W * H;
    return;
  }
  per_texel_.resize(static_cast<std::size_t>(W) * H);
  // Row sums in parallel, then a serial sum: the total does not depend on the thread count.
  std::vector<double> row_sums(H, 0.0);
  tbb::parallel_for(0, H, [&](int j) {
    double row = 0.0;
    for (int i = 0; i < W; ++i) {
      const double w = param.texel_solid_angle(i, j);
      per_texel_[static_cast<std::size_t>(j) * W + i] = static_cast<float>(w);
      row += w;
    }
    row_sums[j] = row;
  });
  for (double r : row_sums) total_ += r;
}

}  // namespace envkit
