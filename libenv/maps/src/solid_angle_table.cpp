#include <envkit/maps/cubemap.h>
#include <envkit/maps/solid_angle_table.h>
#include <tbb/parallel_for.h>

namespace envkit {

SolidAngleTable::SolidAngleTable(const Parameterization& param) : width_(param.width()) {
  const int W = param.width(), H = param.height();
  if (param.kind() == Kind::LatLong) {
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
  if (const auto* cube = dynamic_cast<const CubeMap*>(&param)) {
    fill_cube(*cube);
    return;
  }
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

// Every face has the same texel grid, symmetric under the face's mirror lines and its diagonal: the solid angles
// of one eighth of one face give them all (48x fewer evaluations of four atan2).
void SolidAngleTable::fill_cube(const CubeMap& cube) {
  const int n = cube.face_size();
  const CubeFace& f0 = cube.face(0);
  std::vector<double> face(static_cast<std::size_t>(n) * n);
  const int half = (n + 1) / 2;
  tbb::parallel_for(0, half, [&](int j) {
    for (int i = j; i < half; ++i) {
      const double w = cube.texel_solid_angle(f0.origin_x + i, f0.origin_y + j);
      for (const auto& [a, b] : {std::pair{i, j}, std::pair{j, i}})
        for (const int x : {a, n - 1 - a})
          for (const int y : {b, n - 1 - b}) face[static_cast<std::size_t>(y) * n + x] = w;
    }
  });
  double face_total = 0.0;
  for (double w : face) face_total += w;
  for (int f = 0; f < 6; ++f) {
    const CubeFace& cf = cube.face(f);
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        per_texel_[static_cast<std::size_t>(cf.origin_y + y) * width_ + cf.origin_x + x] =
            static_cast<float>(face[static_cast<std::size_t>(y) * n + x]);
  }
  total_ = 6.0 * face_total;
}

}  // namespace envkit
