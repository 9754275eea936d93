#include <envkit/core/error.h>
#include <envkit/maps/octahedral.h>
#include <envkit/sampling/distribution_refined.h>
#include <envkit/sampling/lobe_product.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace envkit {

namespace {

constexpr int kCellColumns = 32;  // the cell level: its width nearest to this in log2
constexpr int kAxisBinsCosine = 16;
constexpr int kAxisBinsGgx = 32;
constexpr double kFloorFraction = 0.1;

/// The direction at continuous texel coordinates (X, Y) of the grid.
Vec3 grid_direction(const SphericalDistribution& env, double X, double Y) {
  const int x = std::clamp(int(X), 0, env.width() - 1), y = std::clamp(int(Y), 0, env.height() - 1);
  return env.direction_in_texel(x, y, std::clamp(X - x, 0.0, 1.0), std::clamp(Y - y, 0.0, 1.0));
}

/// A cone holding the node's directions: its centre (the middle of the texels it covers) and the largest angle
/// from it to the node's corners and edge midpoints (a bound for the small nodes this is used on).
struct Cone {
  Vec3 centre;
  double radius = 0.0;
};
Cone node_cone(const SphericalDistribution& env, int k, int i, int j) {
  const double span = double(1 << k);
  const double x0 = i * span, x1 = std::min((i + 1) * span, double(env.width()));
  const double y0 = j * span, y1 = std::min((j + 1) * span, double(env.height()));
  Cone cone{grid_direction(env, 0.5 * (x0 + x1), 0.5 * (y0 + y1))};
  for (double fy : {0.0, 0.5, 1.0})
    for (double fx : {0.0, 0.5, 1.0})
      cone.radius = std::max(cone.radius,
                             angle_between(cone.centre, grid_direction(env, x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))));
  return cone;
}

/// cos(max(0, theta - delta)) for cos theta = c: the largest cosine to a direction within delta of the axis
/// (delta in [0, pi], given by its cosine and sine).
double widened_cosine(double c, double cos_delta, double sin_delta) {
  if (c >= cos_delta) return 1.0;
  return c * cos_delta + std::sqrt(std::max(0.0, 1.0 - c * c)) * sin_delta;
}

/// cos and sin of min(pi, a + b) from those of a and b (each in [0, pi]).
void add_angles(double ca, double sa, double cb, double sb, double& c, double& s) {
  c = ca * cb - sa * sb;
  s = sa * cb + ca * sb;
  if (s < 0.0) {  // past pi
    c = -1.0;
    s = 0.0;
  }
}

}  // namespace

double Lobe::value(double c) const {
  if (!(c > -1.0)) return 0.0;
  c = std::min(c, 1.0);
  if (shape == Shape::Cosine) return std::max(c, 0.0);
  const double a2 = alpha * alpha;
  const double cos_h2 = 0.5 * (1.0 + c);  // cos^2 of the half angle
  const double t = cos_h2 * (a2 - 1.0) + 1.0;
  const double v = a2 / (kPi * t * t) / 4.0;
  return std::isfinite(v) ? v : 0.0;
}

LobeProductTables::LobeProductTables(const SphericalDistribution& env, std::vector<Lobe> lobes)
    : lobes_(std::move(lobes)) {
  if (env.distribution().builtin() != BuiltinDistribution::Hierarchical)
    throw Error(std::string("product tables need the hierarchical environment table, got '") +
                env.distribution().method() + "'");
  const auto fine = std::static_pointer_cast<const HierarchicalDistribution2D>(env.distribution_ptr());
  if (lobes_.empty()) throw Error("product tables: no lobe");
  for (const Lobe& l : lobes_)
    if (l.shape == Lobe::Shape::Ggx && !(l.alpha >= 1e-3 && l.alpha <= 1.0))
      throw Error("product tables: GGX alpha " + std::to_string(l.alpha) + " outside [0.001, 1]");
  // The cell level: its width nearest to kCellColumns in log2; the sub-node level below it.
  const double target = std::log2(double(kCellColumns));
  double best = 1e300;
  int level = 0;
  for (int k = 0; k <= fine->levels(); ++k) {
    const double d = std::abs(std::log2(double(fine->level_width(k))) - target);
    if (d < best - 1e-12) {
      best = d;
      level = k;
    }
  }
  int sub = std::max(0, level - 1);
  // HEALPix: a sub-node must lie inside one base pixel (N_side = width / 4 texels square) for its cone to hold it;
  // cells may group sub-nodes of base pixels that are not neighbours (only their sum is used).
  if (env.grid() == Kind::HEALPix)
    while (sub > 0 && (env.width() / 4) % (1 << sub) != 0) --sub;
  const int cw = fine->level_width(level), ch = fine->level_height(level);
  const int sw = fine->level_width(sub), sh = fine->level_height(sub);
  // Sub-nodes: centre and environment sum, grouped by cell.
  struct SubNode {
    Vec3 centre;
    double cos_radius, sin_radius;
    double env;
    double solid_angle;
  };
  std::vector<std::vector<SubNode>> by_cell(std::size_t(cw) * std::size_t(ch));
  for (int j = 0; j < sh; ++j)
    for (int i = 0; i < sw; ++i) {
      const double e = fine->node(sub, i, j);
      if (!(e > 0.0)) continue;
      const int shift = level - sub;
      const Cone cone = node_cone(env, sub, i, j);
      // Every grid's texel solid angle depends on its row alone (lat-long; octahedral and HEALPix are equal-area).
      const int x0 = i << sub, x1 = std::min((i + 1) << sub, env.width());
      double omega = 0.0;
      for (int y = j << sub; y < std::min((j + 1) << sub, env.height()); ++y)
        omega += (x1 - x0) * env.texel_solid_angle(x0, y);
      by_cell[std::size_t(j >> shift) * std::size_t(cw) + std::size_t(i >> shift)].push_back(
          {cone.centre, std::cos(cone.radius), std::sin(cone.radius), e, omega});
    }
  std::vector<double> cell_env(by_cell.size());
  double env_total = 0.0;
  for (int j = 0; j < ch; ++j)
    for (int i = 0; i < cw; ++i)
      env_total += cell_env[std::size_t(j) * std::size_t(cw) + std::size_t(i)] = fine->node(level, i, j);

  std::size_t count = 0;
  for (const Lobe& l : lobes_) {
    const int B = l.shape == Lobe::Shape::Cosine ? kAxisBinsCosine : kAxisBinsGgx;
    bins_.push_back(B);
    first_.push_back(count);
    count += std::size_t(B) * std::size_t(B);
  }
  const auto store = std::make_shared<RefinedCellStore>(fine, level, count);
  mean_.assign(count, 0.0);
  tbb::parallel_for(std::size_t(0), count, [&](std::size_t t) {
    const std::size_t l = std::size_t(std::upper_bound(first_.begin(), first_.end(), t) - first_.begin()) - 1;
    const int B = bins_[l];
    const std::size_t bin = t - first_[l];
    // The lobe is evaluated at the closest approach of the bin's axes and the sub-node's directions, so that no
    // point's lobe is cut where the table's is 0 (at a horizon: a bright window just above a point's horizon but
    // below the bin centre's would otherwise be found by the floor alone).
    const double bx = double(bin % std::size_t(B)), by = double(bin / std::size_t(B));
    const Vec3 axis = OctahedralMap::direction_from_unit(Vec2((bx + 0.5) / B, (by + 0.5) / B));
    double bin_radius = 0.0;
    for (double fy : {0.0, 0.5, 1.0})
      for (double fx : {0.0, 0.5, 1.0})
        bin_radius = std::max(
            bin_radius, angle_between(axis, OctahedralMap::direction_from_unit(Vec2((bx + fx) / B, (by + fy) / B))));
    const double cos_bin = std::cos(bin_radius), sin_bin = std::sin(bin_radius);
    std::vector<double> w(by_cell.size(), 0.0);
    double lobe_total = 0.0, lobe_solid_angle = 0.0;
    for (std::size_t c = 0; c < by_cell.size(); ++c) {
      double s = 0.0;
      for (const SubNode& n : by_cell[c]) {
        double cos_delta, sin_delta;
        add_angles(cos_bin, sin_bin, n.cos_radius, n.sin_radius, cos_delta, sin_delta);
        const double v = lobes_[l].value(widened_cosine(axis ^ n.centre, cos_delta, sin_delta));
        s += n.env * v;
        lobe_solid_angle += n.solid_angle * v;
      }
      w[c] = s;
      lobe_total += s;
    }
    mean_[t] = lobe_solid_angle > 0.0 ? lobe_total / lobe_solid_angle : 0.0;
    // Normalised before rounding to float: env sums times a narrow lobe's peak may exceed the float range.
    const double floor_per_env = kFloorFraction * (lobe_total > 0.0 ? lobe_total / env_total : 1.0);
    const double scale = 1.0 / (lobe_total + floor_per_env * env_total);
    std::vector<float> weights(w.size());
    // At least the smallest normal float on every cell with light: a cell with a 1e-40 share of the map's light
    // still gets pdf > 0 (a float rounding it to 0 would bias every estimator without BSDF samples).
    for (std::size_t c = 0; c < w.size(); ++c)
      weights[c] = cell_env[c] > 0.0 ? std::max(float((w[c] + floor_per_env * cell_env[c]) * scale), FLT_MIN) : 0.0f;
    store->build(t, weights);
  });
  // The distributions side by side (one allocation), each sharing the ownership of the vector.
  auto refined = std::make_shared<std::vector<RefinedDistribution2D>>();
  refined->reserve(count);
  for (std::size_t t = 0; t < count; ++t) refined->emplace_back(store, t);
  tables_.reserve(count);
  for (std::size_t t = 0; t < count; ++t)
    tables_.emplace_back(env, std::shared_ptr<const Distribution2D>(refined, &(*refined)[t]));
}

std::size_t LobeProductTables::table_index(int lobe, const Vec3& axis) const {
  if (lobe < 0 || lobe >= int(lobes_.size()))
    throw Error("product tables: lobe " + std::to_string(lobe) + " of " + std::to_string(lobes_.size()));
  const int B = bins_[std::size_t(lobe)];
  const Vec2 p = OctahedralMap::unit_from_direction(axis);
  const auto bin = [B](double t) { return t > 0.0 ? std::min(int(t * B), B - 1) : 0; };  // NaN -> 0
  const int bx = bin(p.x), by = bin(p.y);
  return first_[std::size_t(lobe)] + std::size_t(by) * std::size_t(B) + std::size_t(bx);
}

LobeProductTables::Table LobeProductTables::table(int lobe, const Vec3& axis) const {
  const std::size_t i = table_index(lobe, axis);
  return {tables_[i], mean_[i]};
}

int LobeProductTables::find(const Lobe& lobe) const {
  const auto it = std::find(lobes_.begin(), lobes_.end(), lobe);
  return it == lobes_.end() ? -1 : int(it - lobes_.begin());
}

std::size_t LobeProductTables::bytes() const {
  std::size_t b = sizeof(*this);
  for (const SphericalDistribution& t : tables_) b += sizeof(t) + t.distribution().bytes();
  return b;
}

}  // namespace envkit
