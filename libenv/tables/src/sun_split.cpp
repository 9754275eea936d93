#include <envkit/core/error.h>
#include <envkit/core/vec.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/param_factory.h>
#include <envkit/sampling/distribution_sparse.h>
#include <envkit/tables/sun_split.h>

#include <algorithm>
#include <cmath>
#include <functional>

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
        widest = std::max(widest, safe_acos(d ^ axis));
      }
  }
  return std::min(kPi, widest + texel_width);
}

/// The tables' distribution grid as a map.
std::unique_ptr<Parameterization> grid_of(const EnvTables& tables) {
  ParamSpec spec;
  spec.kind = tables.grid();
  spec.width = tables.width();
  spec.height = tables.height();
  return make_parameterization(spec);
}

/// The residual table of `method`: the importance with the sun's texels at 0; `compensated`: max(that - its
/// solid-angle mean, 0), unless that is zero everywhere (a constant residual keeps its plain importance, as the
/// bake does). Null when the rest of the map carries no light: its table would fall back to uniform sampling, whose
/// samples land on the sun's texels too, and the sun would be counted twice.
std::shared_ptr<const StoredTable> residual_table(const EnvTables& tables, const std::vector<std::size_t>& sun_texels,
                                                  SamplingMethod method, bool compensated) {
  const int W = tables.width(), H = tables.height();
  std::vector<float> residual(tables.importance().begin(), tables.importance().end());
  for (std::size_t t : sun_texels) residual[t] = 0.0f;
  if (std::none_of(residual.begin(), residual.end(), [](float v) { return v > 0.0f; })) return nullptr;
  if (compensated) {
    const auto grid = grid_of(tables);
    double power = 0.0;
    for (int y = 0; y < H; ++y) {
      double row = 0.0;
      for (int x = 0; x < W; ++x) row += residual[std::size_t(y) * W + x];
      power += row * grid->solid_angle(0.0, y, 1.0, y + 1.0);
    }
    const float mean = float(power / kFourPi);
    bool any = false;
    for (float v : residual) any |= v > mean;
    if (any)
      for (float& v : residual) v = std::max(v - mean, 0.0f);
  }
  return make_table(tables.grid(), W, H, residual, method);
}

}  // namespace

std::optional<SunSplit> SunSplit::find(const EnvTables& tables, const SunOptions& options) {
  const int W = tables.width(), H = tables.height();
  const std::span<const float> importance = tables.importance();
  EnvMap map;
  map.param = grid_of(tables);
  map.image = Image(W, H, 1);
  std::copy(importance.begin(), importance.end(), map.image.pixels.begin());
  std::optional<SunEstimate> sun = detect_sun(map, options);
  if (!sun) return std::nullopt;

  SunSplit split;
  // Weights as make_table() forms them: importance x the exact solid angle of the row's texels (the same for every
  // texel of a row on these grids).
  std::vector<std::uint64_t> sun_texels(sun->region.begin(), sun->region.end());
  std::vector<float> sun_weights(sun_texels.size());
  for (std::size_t k = 0; k < sun_texels.size(); ++k) {
    const int y = int(sun_texels[k] / std::uint64_t(W));
    sun_weights[k] = float(double(importance[sun_texels[k]]) * map.param->solid_angle(0.0, y, 1.0, y + 1.0));
  }
  split.sun_distribution_ = std::make_shared<StoredTable>(
      tables.grid(), std::make_shared<SparseDistribution2D>(W, H, sun_texels, sun_weights));
  split.cos_bound_ = std::cos(bounding_angle(*split.sun_distribution_, sun->direction, sun->region));
  split.sun_ = std::move(*sun);
  return split;
}

std::optional<SunSplit> SunSplit::make(const EnvTables& tables, SamplingMethod method, bool compensated,
                                       const SunOptions& options) {
  std::optional<SunSplit> split = find(tables, options);
  if (!split) return std::nullopt;
  split->residual_ = residual_table(tables, split->sun_.region, method, compensated);
  if (!split->residual_) return std::nullopt;  // the sun is all the light: one table samples it as well
  return split;
}

SunSplit SunSplit::with_method(const EnvTables& tables, SamplingMethod method, bool compensated) const {
  SunSplit split = *this;
  split.residual_ = residual_table(tables, sun_.region, method, compensated);
  if (!split.residual_) throw Error("sun split: the rest of the map carries no light");  // make() did not split
  return split;
}

void SunSplit::save_sun(BlobWriter& out) const {
  for (double v : {sun_.direction.x, sun_.direction.y, sun_.direction.z, sun_.solid_angle, sun_.angular_radius})
    out.scalar(v);
  for (double v : sun_.power) out.scalar(v);
  for (double v : sun_.radiance) out.scalar(v);
  for (double v : {sun_.power_share, sun_.peak_luminance, sun_.median_luminance, cos_bound_}) out.scalar(v);
  out.scalar<std::int64_t>(sun_.clipped ? sun_.clipped_texels : -1);
  static_assert(sizeof(std::size_t) == sizeof(std::uint64_t));
  out.array(sun_.region);
  sun_distribution_->stored().save(out);
}

SunSplit SunSplit::restore(BlobReader& in, Kind grid, int width, int height,
                           std::shared_ptr<const StoredTable> residual) {
  const auto refuse = [&](const std::string& what) { return Error(in.context() + ": invalid sun (" + what + ")"); };
  SunSplit split;
  SunEstimate& sun = split.sun_;
  sun.direction.x = in.scalar<double>();
  sun.direction.y = in.scalar<double>();
  sun.direction.z = in.scalar<double>();
  sun.solid_angle = in.scalar<double>();
  sun.angular_radius = in.scalar<double>();
  for (double& v : sun.power) v = in.scalar<double>();
  for (double& v : sun.radiance) v = in.scalar<double>();
  sun.power_share = in.scalar<double>();
  sun.peak_luminance = in.scalar<double>();
  sun.median_luminance = in.scalar<double>();
  split.cos_bound_ = in.scalar<double>();
  const auto clipped = in.scalar<std::int64_t>();
  const std::vector<std::uint64_t> region = in.array<std::uint64_t>();
  auto texels = std::make_shared<SparseDistribution2D>(in);
  in.finish();

  const Vec3& d = sun.direction;
  if (!(std::abs(std::sqrt(d ^ d) - 1.0) <= 1e-9)) throw refuse("direction is not a unit vector");
  const auto non_negative = [](double v) { return v >= 0.0 && std::isfinite(v); };
  for (double v : {sun.solid_angle, sun.angular_radius, sun.peak_luminance, sun.median_luminance, sun.power[0],
                   sun.power[1], sun.power[2], sun.radiance[0], sun.radiance[1], sun.radiance[2]})
    if (!non_negative(v)) throw refuse("a size or power is not finite and >= 0");
  if (!(sun.power_share >= 0.0 && sun.power_share <= 1.0)) throw refuse("share of the light outside [0, 1]");
  if (!(split.cos_bound_ >= -1.0 && split.cos_bound_ <= 1.0)) throw refuse("bound outside [-1, 1]");
  const std::uint64_t texel_count = std::uint64_t(width) * std::uint64_t(height);
  if (region.empty() || region.back() >= texel_count ||
      std::adjacent_find(region.begin(), region.end(), std::greater_equal<>()) != region.end())
    throw refuse("texels not ascending inside the grid");
  if (clipped < -1 || clipped > std::int64_t(region.size())) throw refuse("clipped texel count");
  if (texels->width() != width || texels->height() != height) throw refuse("its texels are on another grid");
  for (std::uint64_t t : texels->texels())
    if (!std::binary_search(region.begin(), region.end(), t)) throw refuse("a sampled texel outside the sun");
  if (!residual || residual->grid() != grid || residual->width() != width || residual->height() != height)
    throw refuse("the residual table is on another grid");
  // The two parts are weighed as disjoint (sun_split.h): a residual with light on the sun's texels would count it
  // twice.
  for (std::uint64_t t : region)
    if (residual->texel_pdf(int(t % std::uint64_t(width)), int(t / std::uint64_t(width))) != 0.0)
      throw refuse("the residual table has light on the sun's texels");
  sun.clipped = clipped >= 0;
  sun.clipped_texels = sun.clipped ? int(clipped) : 0;
  sun.texels = int(region.size());
  sun.region.assign(region.begin(), region.end());
  split.sun_distribution_ = std::make_shared<StoredTable>(grid, std::move(texels));
  split.residual_ = std::move(residual);
  return split;
}

}  // namespace envkit
