#include <envkit/distribution_sparse.h>
#include <envkit/envmap.h>
#include <envkit/error.h>
#include <envkit/param_factory.h>
#include <envkit/sun_split.h>

#include <algorithm>
#include <cmath>

namespace envkit {

namespace {

/// The half-angle of a cone about `axis` that holds every direction of `texels`: the widest of nine points per
/// texel (corners, edge midpoints, centre) plus one texel's width, so that a texel's edges, which need not be
/// great circles, stay inside.
double bounding_angle(const SphericalDistribution& grid, const Vec3& axis, const std::vector<std::size_t>& texels) {
  double widest = 0.0, texel_width = 0.0;
  const int W = grid.width();
  for (std::size_t t : texels) {
    const int x = int(t % std::size_t(W)), y = int(t / std::size_t(W));
    texel_width = std::max(texel_width, std::sqrt(grid.texel_solid_angle(x, y)));
    for (double fy : {0.0, 0.5, 1.0})
      for (double fx : {0.0, 0.5, 1.0}) {
        const Vec3 d = grid.direction_in_texel(x, y, fx, fy);
        widest = std::max(widest, std::acos(std::clamp(d ^ axis, -1.0, 1.0)));
      }
  }
  return std::min(kPi, widest + texel_width);
}

}  // namespace

std::optional<SunSplit> SunSplit::make(const EnvTables& tables, SamplingMethod method, bool compensated,
                                       const SunOptions& options) {
  const int W = tables.width(), H = tables.height();
  const std::span<const float> importance = tables.importance();
  ParamSpec spec;
  spec.kind = tables.grid();
  spec.width = W;
  spec.height = H;
  EnvMap map;
  map.param = make_parameterization(spec);
  map.image = Image(W, H, 1);
  std::copy(importance.begin(), importance.end(), map.image.pixels.begin());
  std::optional<SunEstimate> sun = detect_sun(map, options);
  if (!sun) return std::nullopt;

  SunSplit split;
  // The residual is the copy detect_sun read, with the sun's texels at 0 (one grid-sized buffer fewer).
  const std::span<float> residual(map.image.pixels.data(), importance.size());
  std::vector<float> sun_importance(sun->region.size());
  std::vector<std::uint64_t> sun_texels(sun->region.begin(), sun->region.end());
  for (std::size_t k = 0; k < sun->region.size(); ++k) {
    sun_importance[k] = residual[sun->region[k]];
    residual[sun->region[k]] = 0.0f;
  }
  // Weights as make_table() forms them: importance x the exact solid angle of the row's texels (the same for every
  // texel of a row on these grids).
  const auto row_omega = [&](int y) { return map.param->solid_angle(0.0, y, 1.0, y + 1.0); };
  std::vector<float> sun_weights(sun_importance.size());
  for (std::size_t k = 0; k < sun_texels.size(); ++k)
    sun_weights[k] = float(double(sun_importance[k]) * row_omega(int(sun_texels[k] / std::uint64_t(W))));
  split.sun_distribution_ = std::make_unique<SphericalDistribution>(
      tables.grid(), std::make_shared<SparseDistribution2D>(W, H, sun_texels, sun_weights));

  if (compensated) {
    double power = 0.0;
    for (int y = 0; y < H; ++y) {
      double row = 0.0;
      for (int x = 0; x < W; ++x) row += residual[std::size_t(y) * W + x];
      power += row * row_omega(y);
    }
    const float mean = float(power / kFourPi);
    bool any = false;
    for (float v : residual) any |= v > mean;
    if (any)  // a constant residual keeps its plain importance, as the bake does
      for (float& v : residual) v = std::max(v - mean, 0.0f);
  }
  split.residual_ = make_table(tables.grid(), W, H, residual, method);
  split.cos_bound_ = std::cos(bounding_angle(*split.sun_distribution_, sun->direction, sun->region));
  split.sun_ = std::move(*sun);
  return split;
}

}  // namespace envkit
