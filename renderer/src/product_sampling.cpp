/// BSDF x environment product sampling by hierarchical warping (see product_sampling.h).
#include <envkit/render/product_sampling.h>

#include <envkit/distribution_pyramid.h>
#include <envkit/error.h>
#include <envkit/octahedral.h>

#include <algorithm>
#include <cmath>

namespace envkit::render {

namespace {

using sampling::clamp_decision;
using sampling::clamp_offset;

const PyramidDistribution2D& require_pyramid(const SphericalDistribution& env) {
  const auto* p = dynamic_cast<const PyramidDistribution2D*>(&env.distribution());
  if (p == nullptr)
    throw Error(std::string("product sampling needs the hierarchical (pyramid) environment distribution, got '") +
                env.distribution().method() + "'");
  return *p;
}

/// The scalar the product table uses for an RGB BSDF value.
inline double mean_rgb(const Vec3& v) { return (v.x + v.y + v.z) * (1.0 / 3.0); }

bool finite_nonzero(const Vec3& d) {
  const double n2 = d.length2();
  return std::isfinite(n2) && n2 > 0.0;
}

/// One hierarchical decision among the children c = {c00, c10, c01, c11} of a node, exactly as
/// PyramidDistribution2D::sample: u.x picks the column pair, u.y the child in it; both re-uniformised and clamped.
/// False when the node's sum is 0 (never for a node reached with positive probability).
inline bool descend(const double c[4], double& ux, double& uy, int& dx, int& dy) {
  const double left = c[0] + c[2], right = c[1] + c[3];
  const double tx = ux * (left + right);
  if (tx < left) {
    dx = 0;
    ux = clamp_decision(tx / left);
  } else {
    if (!(right > 0.0)) return false;
    dx = 1;
    ux = clamp_decision((tx - left) / right);
  }
  const double top = c[dx], bottom = c[2 + dx];
  const double ty = uy * (top + bottom);
  if (ty < top) {
    dy = 0;
    uy = clamp_decision(ty / top);
  } else {
    if (!(bottom > 0.0)) return false;
    dy = 1;
    uy = clamp_decision((ty - top) / bottom);
  }
  return true;
}

/// Lat-long table-frame direction for horizontal texel coordinate X (longitude linear) and cos theta.
inline Vec3 latlong_direction(double X, int width, double cos_theta) {
  const double lon = kPi - kTwoPi * (X / width);
  const double sin_theta = safe_sqrt(1.0 - cos_theta * cos_theta);
  return Vec3(std::sin(lon) * sin_theta, cos_theta, std::cos(lon) * sin_theta);
}

}  // namespace

ProductSampler::ProductSampler(const SphericalDistribution& env_hierarchical, const Mat3& world_from_table,
                               int product_resolution)
    : ProductSampler(env_hierarchical, world_from_table, product_resolution, Options()) {}

ProductSampler::ProductSampler(const SphericalDistribution& env_hierarchical, const Mat3& world_from_table,
                               int product_resolution, const Options& options)
    : env_(env_hierarchical), pyramid_(require_pyramid(env_hierarchical)), world_from_table_(world_from_table),
      table_from_world_(transposed(world_from_table)), options_(options) {
  if (!(options_.floor_fraction > 0.0)) options_.floor_fraction = 0.02;
  // Coarse level: node columns nearest to product_resolution in log2.
  const double target = std::log2(double(std::max(1, product_resolution)));
  coarse_level_ = pyramid_.levels();
  double best = 1e300;
  for (int k = 0; k <= pyramid_.levels(); ++k) {
    const double d = std::abs(std::log2(double(pyramid_.level_width(k))) - target);
    if (d < best - 1e-12) {
      best = d;
      coarse_level_ = k;
    }
  }
  coarse_w_ = pyramid_.level_width(coarse_level_);
  coarse_h_ = pyramid_.level_height(coarse_level_);
  if (options_.points_per_axis <= 0) options_.points_per_axis = coarse_w_ <= 16 ? 2 : 1;
  options_.points_per_axis = std::min(options_.points_per_axis, 16);
  for (int k = coarse_level_; k <= pyramid_.levels(); ++k) {
    level_w_.push_back(pyramid_.level_width(k));
    level_h_.push_back(pyramid_.level_height(k));
    levels_.emplace_back(std::size_t(level_w_.back()) * std::size_t(level_h_.back()), 0.0);
  }
  bsdf_.assign(std::size_t(coarse_w_) * std::size_t(coarse_h_), 0.0);
  precompute_nodes();
}

void ProductSampler::precompute_nodes() {
  const int S = options_.points_per_axis;
  const int W = env_.width(), H = env_.height();
  const int span = 1 << coarse_level_;
  node_points_.resize(std::size_t(coarse_w_) * std::size_t(coarse_h_) * std::size_t(S * S));
  node_cones_.resize(std::size_t(coarse_w_) * std::size_t(coarse_h_));
  // Table-frame direction at continuous texel coordinates (X, Y) (lat-long: Y -> cos theta linear in theta's
  // row position; only used for node points and bounds, not for sampling).
  const auto direction_at = [&](double X, double Y) {
    if (env_.grid() == Kind::Octahedral) {
      Vec3 d;
      OctahedralMap(W).to_direction(Vec2(X, Y), d);
      return d;
    }
    return latlong_direction(X, W, std::cos(kPi * Y / H));
  };
  for (int j = 0; j < coarse_h_; ++j)
    for (int i = 0; i < coarse_w_; ++i) {
      const double x0 = double(i * span), x1 = double(std::min((i + 1) * span, W));
      const double y0 = double(j * span), y1 = double(std::min((j + 1) * span, H));
      const std::size_t node = std::size_t(j) * std::size_t(coarse_w_) + std::size_t(i);
      // Points: S x S cell centres, uniform in solid angle (lat-long: cos theta linear between the node's rows).
      const double z0 = std::cos(kPi * y0 / H), z1 = std::cos(kPi * y1 / H);
      for (int b = 0; b < S; ++b)
        for (int a = 0; a < S; ++a) {
          const double X = x0 + (x1 - x0) * (a + 0.5) / S;
          Vec3 d;
          if (env_.grid() == Kind::Octahedral)
            d = direction_at(X, y0 + (y1 - y0) * (b + 0.5) / S);
          else
            d = latlong_direction(X, W, z0 + (z1 - z0) * (b + 0.5) / S);
          node_points_[node * std::size_t(S * S) + std::size_t(b * S + a)] = apply(world_from_table_, d).normalized();
        }
      // Bounding cone: centre and the largest angle to 16 points per boundary edge, plus half the largest gap
      // between neighbouring boundary points (no boundary point is farther than that from a sampled one; the
      // farthest point of a cell smaller than a hemisphere lies on its boundary).
      NodeCone& cone = node_cones_[node];
      const Vec3 centre = direction_at(0.5 * (x0 + x1), 0.5 * (y0 + y1));
      constexpr int kEdge = 16;
      double max_angle = 0.0, max_gap = 0.0;
      Vec3 previous;
      bool first = true;
      const auto visit = [&](double X, double Y) {
        const Vec3 d = direction_at(X, Y);
        max_angle = std::max(max_angle, angle_between(centre, d));
        if (!first) max_gap = std::max(max_gap, angle_between(previous, d));
        previous = d;
        first = false;
      };
      for (int e = 0; e < kEdge; ++e) visit(x0 + (x1 - x0) * e / kEdge, y0);
      for (int e = 0; e < kEdge; ++e) visit(x1, y0 + (y1 - y0) * e / kEdge);
      for (int e = 0; e < kEdge; ++e) visit(x1 - (x1 - x0) * e / kEdge, y1);
      for (int e = 0; e <= kEdge; ++e) visit(x0, y1 - (y1 - y0) * e / kEdge);
      const double radius = max_angle + 0.5 * max_gap + 1e-9;
      cone.centre = apply(world_from_table_, centre).normalized();
      cone.all_sphere = radius >= 0.5 * kPi || coarse_w_ * coarse_h_ <= 2;
      cone.sin_radius = cone.all_sphere ? 1.0 : std::sin(radius);
    }
}

void ProductSampler::prepare(const Material& m, const Frame& frame, const Vec3& wo_local) {
  material_ = &m;
  frame_ = frame;
  wo_local_ = wo_local;
  valid_ = false;
  total_ = 0.0;
  for (auto& level : levels_) std::fill(level.begin(), level.end(), 0.0);
  if (!(wo_local.z > 0.0) || m.is_pure_delta() || !finite_nonzero(wo_local)) return;

  // BSDF table: mean over the node's points of mean_rgb(eval), on nodes that can see above the horizon.
  const int S2 = options_.points_per_axis * options_.points_per_axis;
  const std::size_t nodes = bsdf_.size();
  double sum_b = 0.0;
  std::size_t touching = 0;
  for (std::size_t node = 0; node < nodes; ++node) {
    const NodeCone& cone = node_cones_[node];
    // Node entirely below the shading horizon: angle(centre, n) >= 90 deg + radius <=> centre.n <= -sin(radius).
    if (!cone.all_sphere && (cone.centre ^ frame.n) <= -cone.sin_radius) {
      bsdf_[node] = -1.0;  // marks "no support"
      continue;
    }
    double b = 0.0;
    const Vec3* points = node_points_.data() + node * std::size_t(S2);
    for (int p = 0; p < S2; ++p) {
      const Vec3 wi = frame.to_local(points[p]);
      if (wi.z > 0.0) b += mean_rgb(m.eval(wo_local, wi));
    }
    b = std::isfinite(b) ? b / S2 : 0.0;
    bsdf_[node] = b;
    sum_b += b;
    ++touching;
  }
  if (touching == 0) return;
  const double floor = sum_b > 0.0 ? options_.floor_fraction * sum_b / double(touching) : 1.0;

  // Product weights at the coarse level, then the double sum pyramid above it.
  const int c = coarse_level_;
  std::vector<double>& base = levels_[0];
  for (int j = 0; j < coarse_h_; ++j)
    for (int i = 0; i < coarse_w_; ++i) {
      const std::size_t node = std::size_t(j) * std::size_t(coarse_w_) + std::size_t(i);
      const double b = bsdf_[node];
      base[node] = b < 0.0 ? 0.0 : pyramid_.node(c, i, j) * (b + floor);
    }
  for (std::size_t m1 = 1; m1 < levels_.size(); ++m1) {
    const int w = level_w_[m1], h = level_h_[m1], cw = level_w_[m1 - 1], ch = level_h_[m1 - 1];
    const std::vector<double>& below = levels_[m1 - 1];
    std::vector<double>& here = levels_[m1];
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i) {
        double s = 0.0;
        for (int d = 0; d < 4; ++d) {
          const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
          if (x < cw && y < ch) s += below[std::size_t(y) * std::size_t(cw) + std::size_t(x)];
        }
        here[std::size_t(j) * std::size_t(w) + std::size_t(i)] = s;
      }
  }
  total_ = levels_.back()[0];
  valid_ = total_ > 0.0 && std::isfinite(total_);
}

void ProductSampler::product_children(int m, int i, int j, double c[4]) const {
  const int w = level_w_[std::size_t(m)], h = level_h_[std::size_t(m)];
  const std::vector<double>& level = levels_[std::size_t(m)];
  for (int d = 0; d < 4; ++d) {
    const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
    c[d] = (x < w && y < h) ? level[std::size_t(y) * std::size_t(w) + std::size_t(x)] : 0.0;
  }
}

double ProductSampler::coarse_probability(int i, int j) const {
  if (!valid_ || i < 0 || j < 0 || i >= coarse_w_ || j >= coarse_h_) return 0.0;
  return levels_[0][std::size_t(j) * std::size_t(coarse_w_) + std::size_t(i)] / total_;
}

bool ProductSampler::sample(Vec2 u, Vec3& wi_world, double& pdf_out) const {
  if (!valid_) return false;
  double ux = clamp_decision(u.x), uy = clamp_decision(u.y);
  int i = 0, j = 0, dx = 0, dy = 0;
  double c[4];
  // Down the product pyramid to the coarse level.
  for (int m = int(levels_.size()) - 2; m >= 0; --m) {
    product_children(m, i, j, c);
    if (!descend(c, ux, uy, dx, dy)) return false;
    i = 2 * i + dx;
    j = 2 * j + dy;
  }
  const int ci = i, cj = j;
  // Down the environment's own finer levels.
  for (int k = coarse_level_ - 1; k >= 0; --k) {
    c[0] = pyramid_.node(k, 2 * i, 2 * j);
    c[1] = pyramid_.node(k, 2 * i + 1, 2 * j);
    c[2] = pyramid_.node(k, 2 * i, 2 * j + 1);
    c[3] = pyramid_.node(k, 2 * i + 1, 2 * j + 1);
    if (!descend(c, ux, uy, dx, dy)) return false;
    i = 2 * i + dx;
    j = 2 * j + dy;
  }
  const double env_coarse = pyramid_.node(coarse_level_, ci, cj);
  const double leaf = pyramid_.node(0, i, j);
  const double omega = env_.texel_solid_angle(i, j);
  const double p = coarse_probability(ci, cj) * (leaf / env_coarse) / omega;
  if (!(p > 0.0) || !std::isfinite(p)) return false;
  wi_world = apply(world_from_table_, env_.direction_in_texel(i, j, clamp_offset(ux), clamp_offset(uy)));
  pdf_out = p;
  return true;
}

bool ProductSampler::sample(Vec2 u, Vec3& wi_world, double& pdf_out, Vec3& f_cos) const {
  if (!sample(u, wi_world, pdf_out)) return false;
  f_cos = material_->eval(wo_local_, frame_.to_local(wi_world));
  return true;
}

double ProductSampler::pdf(const Vec3& wi_world) const {
  if (!valid_ || !finite_nonzero(wi_world)) return 0.0;
  int x = 0, y = 0;
  env_.texel_of(apply(table_from_world_, wi_world), x, y);
  const int ci = x >> coarse_level_, cj = y >> coarse_level_;
  const double pc = coarse_probability(ci, cj);
  if (!(pc > 0.0)) return 0.0;
  const double env_coarse = pyramid_.node(coarse_level_, ci, cj);
  const double leaf = pyramid_.node(0, x, y);
  if (!(env_coarse > 0.0) || !(leaf > 0.0)) return 0.0;
  const double p = pc * (leaf / env_coarse) / env_.texel_solid_angle(x, y);
  return std::isfinite(p) ? p : 0.0;
}

}  // namespace envkit::render
