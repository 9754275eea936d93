/// BSDF x environment product sampling by hierarchical warping (see product_sampling.h).
#include <envkit/distribution_pyramid.h>
#include <envkit/error.h>
#include <envkit/latlong.h>
#include <envkit/octahedral.h>
#include <envkit/render/product_sampling.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>

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

/// Product sampling bounds each pyramid node by the image rectangle it covers (node points, a cone from its
/// boundary), which needs a map that is continuous across the rectangle. Lat-long and octahedral grids are; the
/// HEALPix layout puts base pixels side by side that are not neighbours on the sphere, so a node spanning two of
/// them would get a wrong cone and could be skipped where the environment has light (a biased image).
void require_continuous_grid(const SphericalDistribution& env) {
  if (env.grid() != Kind::LatLong && env.grid() != Kind::Octahedral)
    throw Error(std::string("product sampling needs a latlong or octahedral table, not ") + kind_name(env.grid()) +
                " (its pyramid nodes span base pixels that are not neighbours on the sphere; re-bake with "
                "envbake --param latlong or octahedral)");
}

/// The GGX alpha of a lobe that a visible-normal sampler draws with the material's peak density at the mirror
/// direction: sqrt(1 / (4 pi cos_o pdf(wo, mirror))); 0 when that density is 0 or not finite (wo.z > 0).
double effective_alpha(const Material& m, const Vec3& wo) {
  const double peak = m.pdf(wo, Vec3(-wo.x, -wo.y, wo.z));
  if (!(peak > 0.0) || !std::isfinite(peak)) return 0.0;
  const double alpha = std::sqrt(1.0 / (4.0 * kPi * wo.z * peak));
  return std::isfinite(alpha) ? alpha : 0.0;
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
  const double lon = LatLongMap::longitude(X / width);
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
  require_continuous_grid(env_);
  if (!(options_.floor_fraction > 0.0)) options_.floor_fraction = 0.02;
  if (!(options_.reuse_angle > 0.0) || !std::isfinite(options_.reuse_angle)) options_.reuse_angle = 0.0;
  options_.reuse_angle = std::min(options_.reuse_angle, 0.5 * kPi);
  if (!(options_.reuse_lobe_fraction > 0.0) || !std::isfinite(options_.reuse_lobe_fraction)) options_.reuse_angle = 0.0;
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
  if (env_.grid() == Kind::LatLong) {
    const int W = env_.width(), H = env_.height();
    for (int k = 0; k <= coarse_level_; ++k) {
      const int span = 1 << k;
      std::vector<Vec2> columns(std::size_t(pyramid_.level_width(k))), rows(std::size_t(pyramid_.level_height(k)));
      for (std::size_t i = 0; i < columns.size(); ++i) {
        const double x0 = double(i) * span, x1 = std::min(double(i + 1) * span, double(W));
        const double lon = LatLongMap::longitude(0.5 * (x0 + x1) / W);
        columns[i] = Vec2(std::sin(lon), std::cos(lon));
      }
      for (std::size_t j = 0; j < rows.size(); ++j) {
        const double y0 = double(j) * span, y1 = std::min(double(j + 1) * span, double(H));
        const double theta = LatLongMap::polar_angle(0.5 * (y0 + y1) / H);
        rows[j] = Vec2(std::sin(theta), std::cos(theta));
      }
      column_centres_.push_back(std::move(columns));
      row_centres_.push_back(std::move(rows));
    }
  }
}

bool ProductSampler::reusable(const Material& m, const Frame& frame, const Vec3& wo_local) const {
  if (!(cos_reuse_ < 1.0) || material_ != &m || !valid_) return false;  // cos_reuse_ < 1 only with reuse on
  return (frame.n ^ frame_.n) >= cos_reuse_ && (frame.to_world(wo_local) ^ prepared_wo_world_) >= cos_reuse_;
}

double ProductSampler::lobe_value(const Vec3& wi) const {
  if (!(wi.z > 0.0)) return 0.0;
  if (lobe_proxy_scale_ > 0.0) {
    const Vec3 h = (wo_local_ + wi).normalized();
    const double t = h.z * h.z * (lobe_a2_ - 1.0) + 1.0;
    const double b = lobe_proxy_scale_ * lobe_a2_ / (kPi * t * t);
    return std::isfinite(b) ? b : 0.0;
  }
  const double b = mean_rgb(material_->eval(wo_local_, wi));
  return b > 0.0 && std::isfinite(b) ? b : 0.0;
}

void ProductSampler::lobe_children(int k, int i, int j, double w[4]) const {
  const std::vector<Vec2>& columns = column_centres_[std::size_t(k)];
  const std::vector<Vec2>& rows = row_centres_[std::size_t(k)];
  double env[4];
  double any = 0.0;
  for (int d = 0; d < 4; ++d) {
    const int x = 2 * i + (d & 1), y = 2 * j + (d >> 1);
    env[d] = pyramid_.node(k, x, y);
    w[d] = 0.0;
    if (!(env[d] > 0.0)) continue;
    const Vec2 c = columns[std::size_t(x)], r = rows[std::size_t(y)];
    const Vec3 d_table(c.x * r.x, r.y, c.y * r.x);
    w[d] = env[d] * lobe_value(apply(local_from_table_, d_table));
    any += w[d];
  }
  if (!(any > 0.0) || !std::isfinite(any))
    for (int d = 0; d < 4; ++d) w[d] = env[d];
}

double ProductSampler::lobe_path_probability(int x, int y) const {
  double p = 1.0;
  for (int k = lobe_level_ - 1; k >= 0; --k) {
    double w[4];
    lobe_children(k, x >> (k + 1), y >> (k + 1), w);
    const double sum = w[0] + w[1] + w[2] + w[3];
    const int d = ((x >> k) & 1) + 2 * ((y >> k) & 1);
    if (!(sum > 0.0) || !(w[d] > 0.0)) return 0.0;
    p *= w[d] / sum;
  }
  return p;
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
    return latlong_direction(X, W, std::cos(LatLongMap::polar_angle(Y / H)));
  };
  for (int j = 0; j < coarse_h_; ++j)
    for (int i = 0; i < coarse_w_; ++i) {
      const double x0 = double(i * span), x1 = double(std::min((i + 1) * span, W));
      const double y0 = double(j * span), y1 = double(std::min((j + 1) * span, H));
      const std::size_t node = std::size_t(j) * std::size_t(coarse_w_) + std::size_t(i);
      // Points: S x S cell centres, uniform in solid angle (lat-long: cos theta linear between the node's rows).
      const double z0 = std::cos(LatLongMap::polar_angle(y0 / H)), z1 = std::cos(LatLongMap::polar_angle(y1 / H));
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
      cone.radius = cone.all_sphere ? kPi : radius;
    }
}

bool ProductSampler::prepare_lobe(const Material& m, const Frame& frame, const Vec3& wo, double alpha,
                                  double& floor) {
  lobe_active_ = false;
  lobe_total_ = 0.0;
  if (options_.lobe_nodes <= 0 || coarse_level_ == 0 || coarse_w_ * coarse_h_ <= 1 || env_.grid() != Kind::LatLong)
    return false;
  // Lobe: a cone around the mirror direction whose width follows the peak sampling density there.
  if (!(alpha > 0.0)) return false;
  const Vec3 mirror(-wo.x, -wo.y, wo.z);
  const double radius = 2.0 * std::atan(options_.lobe_extent * alpha);
  if (!(radius < 0.45 * kPi)) return false;
  const int W = env_.width(), H = env_.height();
  const double texel = LatLongMap::kRadiansPerV / H;
  int level = std::max(0, int(std::ceil(std::log2(2.0 * radius / options_.lobe_nodes / texel))));
  const Vec3 axis = apply(table_from_world_, frame.to_world(mirror)).normalized();
  const Vec2 uv_a = LatLongMap::uv_from_direction(axis);
  const double theta_a = LatLongMap::polar_angle(uv_a.y), lon_a = LatLongMap::longitude(uv_a.x);
  int row0 = 0, rows = 0, col0 = 0, cols = 0, lw = 0;
  level = std::min(level, coarse_level_);
  for (;; ++level) {
    if (level > coarse_level_) return false;
    const int span = 1 << level;
    lw = pyramid_.level_width(level);
    const int lh = pyramid_.level_height(level);
    const double lo = theta_a - radius, hi = theta_a + radius;
    const int j0 = std::max(0, int(std::floor(LatLongMap::v_of_polar_angle(lo) * H / span)));
    const int j1 = std::min(lh - 1, int(std::floor(LatLongMap::v_of_polar_angle(hi) * H / span)));
    row0 = j0;
    rows = j1 - j0 + 1;
    bool full = lo <= 0.0 || hi >= kPi || std::sin(radius) >= std::sin(theta_a);
    if (!full) {
      const double delta = std::asin(std::min(1.0, std::sin(radius) / std::sin(theta_a)));
      const double x_lo = LatLongMap::u_of_longitude(lon_a + delta) * W;
      const double x_hi = LatLongMap::u_of_longitude(lon_a - delta) * W;
      const int i0 = int(std::floor(x_lo / span)), i1 = int(std::floor(x_hi / span));
      cols = i1 - i0 + 1;
      const bool wraps = i0 < 0 || i1 >= lw;
      if (cols >= lw || (wraps && W % span != 0)) {
        full = true;
      } else {
        col0 = ((i0 % lw) + lw) % lw;
      }
    }
    if (full) {
      col0 = 0;
      cols = lw;
    }
    if (rows * cols <= options_.max_lobe_nodes) break;
  }
  lobe_level_ = level;
  lobe_row0_ = row0;
  lobe_rows_ = rows;
  lobe_col0_ = col0;
  lobe_cols_ = cols;
  const std::size_t n = std::size_t(rows) * std::size_t(cols);
  lobe_b_.resize(n);
  lobe_cdf_.resize(n);
  const int span = 1 << level;
  double rho = 0.0, cumulative = 0.0;
  // b per node: the BSDF at the node's centre, or (proxy) the material's sampling density there times
  // f_cos / pdf at the mirror direction (cheaper than eval for microfacet lobes, and of the same shape up to
  // Fresnel and masking); nodes whose centre lies farther than the cone plus the node's half diagonal get 0.
  // Proxy: the GGX D(h) of alpha_eff (the lobe's shape up to Fresnel and masking), scaled to eval at the mirror.
  double proxy = 0.0;
  const double a2 = alpha * alpha;
  if (options_.lobe_proxy) {
    proxy = mean_rgb(m.eval(wo, mirror)) * kPi * a2;
    if (!(proxy > 0.0) || !std::isfinite(proxy)) proxy = 0.0;
  }
  lobe_a2_ = a2;
  lobe_proxy_scale_ = proxy;
  const Mat3 world_from_local(frame.s.x, frame.t.x, frame.n.x, frame.s.y, frame.t.y, frame.n.y, frame.s.z, frame.t.z,
                              frame.n.z);
  local_from_table_ = compose(transposed(world_from_local), world_from_table_);
  const Vec3 mirror_world = frame.to_world(mirror);
  const double node_half = 0.75 * span * texel;  // > half the node's angular diagonal away from the poles
  const double cos_cut = std::cos(std::min(kPi, radius + node_half));
  for (int r = 0; r < rows; ++r) {
    const int j = row0 + r;
    const double y0 = double(j * span), y1 = double(std::min((j + 1) * span, H));
    const double z0 = std::cos(kPi * y0 / H), z1 = std::cos(kPi * y1 / H);
    for (int c = 0; c < cols; ++c) {
      int i = col0 + c;
      if (i >= lw) i -= lw;
      const double x0 = double(i * span), x1 = double(std::min((i + 1) * span, W));
      const Vec2 cc = column_centres_[std::size_t(level)][std::size_t(i)];
      const Vec2 rc = row_centres_[std::size_t(level)][std::size_t(j)];
      const Vec3 dw = apply(world_from_table_, Vec3(cc.x * rc.x, rc.y, cc.y * rc.x));
      double b = 0.0;
      if ((dw ^ mirror_world) >= cos_cut) {
        const Vec3 wi = frame.to_local(dw);
        if (wi.z > 0.0) {
          if (proxy > 0.0) {
            const Vec3 h = (wo + wi).normalized();
            const double c2 = h.z * h.z, t = c2 * (a2 - 1.0) + 1.0;
            b = proxy * a2 / (kPi * t * t);
          } else {
            b = mean_rgb(m.eval(wo, wi));
          }
        }
      }
      if (!(b > 0.0) || !std::isfinite(b)) b = 0.0;
      const std::size_t k = std::size_t(r) * std::size_t(cols) + std::size_t(c);
      lobe_b_[k] = b;
      rho += b * (x1 - x0) * (kTwoPi / W) * (z0 - z1);
      cumulative += b * pyramid_.node(level, i, j);
      lobe_cdf_[k] = cumulative;
    }
  }
  // Floor of the coarse table: the BSDF away from the lobe (plastic's base, GGX tails), estimated at the normal
  // and four directions 60 degrees from it outside the cone, and at least floor_fraction x the lobe's mean.
  double background = 0.0;
  int count = 0;
  const double s60 = std::sqrt(0.75);
  for (const Vec3& wi : {Vec3(0, 0, 1), Vec3(s60, 0, 0.5), Vec3(-s60, 0, 0.5), Vec3(0, s60, 0.5), Vec3(0, -s60, 0.5)}) {
    if (angle_between(wi, mirror) <= radius) continue;
    const double b = mean_rgb(m.eval(wo, wi));
    if (b > 0.0 && std::isfinite(b)) background += b;
    ++count;
  }
  if (count > 0) background /= count;
  floor = std::max(background, options_.floor_fraction * rho / kTwoPi);
  if (!(floor > 0.0) || !std::isfinite(floor)) floor = 1.0;
  lobe_total_ = cumulative;
  lobe_active_ = std::isfinite(cumulative);
  if (!lobe_active_) lobe_total_ = 0.0;
  return true;
}

double ProductSampler::lobe_b(int x, int y) const {
  if (!lobe_active_) return 0.0;
  const int r = (y >> lobe_level_) - lobe_row0_;
  if (r < 0 || r >= lobe_rows_) return 0.0;
  int c = (x >> lobe_level_) - lobe_col0_;
  if (c < 0) c += pyramid_.level_width(lobe_level_);
  if (c >= lobe_cols_) return 0.0;
  return lobe_b_[std::size_t(r) * std::size_t(lobe_cols_) + std::size_t(c)];
}

void ProductSampler::prepare(const Material& m, const Frame& frame, const Vec3& wo_local) {
  material_ = &m;
  frame_ = frame;
  wo_local_ = wo_local;
  valid_ = false;
  lobe_active_ = false;
  total_ = coarse_total_ = lobe_total_ = 0.0;
  for (auto& level : levels_) std::fill(level.begin(), level.end(), 0.0);
  cos_reuse_ = 1.0;
  if (!(wo_local.z > 0.0) || m.is_pure_delta() || !finite_nonzero(wo_local)) return;
  const double alpha = effective_alpha(m, wo_local);  // the lobe's width, for refinement and reuse
  if (options_.reuse_angle > 0.0) {
    prepared_wo_world_ = frame.to_world(wo_local);
    const double angle = std::min(options_.reuse_angle, options_.reuse_lobe_fraction * alpha);
    if (angle > 0.0) cos_reuse_ = std::cos(angle);
  }

  // A lobe narrower than the coarse nodes: its own finer level; the coarse table is then the floor alone.
  double lobe_floor = 0.0;
  const bool lobe = prepare_lobe(m, frame, wo_local, alpha, lobe_floor);

  // BSDF table: mean over the node's points of mean_rgb(eval), on nodes that can see above the horizon.
  const int S2 = options_.points_per_axis * options_.points_per_axis;
  const std::size_t nodes = bsdf_.size();
  double sum_b = 0.0;
  std::size_t touching = 0;
  for (std::size_t node = 0; node < nodes; ++node) {
    const NodeCone& cone = node_cones_[node];
    // Node entirely below the shading horizon: angle(centre, n) >= 90 deg + radius <=> centre.n <= -sin(radius).
    const double margin = cone.radius + options_.reuse_angle;
    if (!cone.all_sphere && margin < 0.5 * kPi && (cone.centre ^ frame.n) <= -std::sin(margin)) {
      bsdf_[node] = -1.0;  // marks "no support"
      continue;
    }
    ++touching;
    if (lobe) {
      bsdf_[node] = 0.0;
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
  }
  if (touching == 0) return;
  const double floor =
      lobe ? lobe_floor : (sum_b > 0.0 ? options_.floor_fraction * sum_b / double(touching) : 1.0);

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
  coarse_total_ = levels_.back()[0];
  total_ = coarse_total_ + lobe_total_;
  valid_ = coarse_total_ > 0.0 && std::isfinite(total_);
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
  int start = coarse_level_;
  bool lobe_path = false;
  const double t = ux * total_;
  if (lobe_active_ && t >= coarse_total_ && lobe_total_ > 0.0) {
    // Lobe part: a node of the lobe rectangle with probability b x env_node / lobe_total.
    const double tl = std::min(t - coarse_total_, lobe_total_);
    const auto it = std::upper_bound(lobe_cdf_.begin(), lobe_cdf_.end(), tl);
    std::size_t k = std::size_t(it - lobe_cdf_.begin());
    if (k >= lobe_cdf_.size()) k = lobe_cdf_.size() - 1;
    while (k > 0 && !(lobe_cdf_[k] > lobe_cdf_[k - 1])) --k;  // never a zero-weight node
    const double below = k > 0 ? lobe_cdf_[k - 1] : 0.0, w = lobe_cdf_[k] - below;
    if (!(w > 0.0)) return false;
    ux = clamp_decision((tl - below) / w);
    const int r = int(k / std::size_t(lobe_cols_)), col = int(k % std::size_t(lobe_cols_));
    j = lobe_row0_ + r;
    i = lobe_col0_ + col;
    if (i >= pyramid_.level_width(lobe_level_)) i -= pyramid_.level_width(lobe_level_);
    start = lobe_level_;
    lobe_path = options_.lobe_descent;
  } else {
    if (lobe_active_) ux = clamp_decision(std::min(t, coarse_total_) / coarse_total_);
    // Down the product pyramid to the coarse level.
    for (int m = int(levels_.size()) - 2; m >= 0; --m) {
      product_children(m, i, j, c);
      if (!descend(c, ux, uy, dx, dy)) return false;
      i = 2 * i + dx;
      j = 2 * j + dy;
    }
  }
  // Down the environment's own finer levels (the lobe part: weighted by the lobe at the children's centres).
  for (int k = start - 1; k >= 0; --k) {
    if (lobe_path) {
      lobe_children(k, i, j, c);
    } else {
      c[0] = pyramid_.node(k, 2 * i, 2 * j);
      c[1] = pyramid_.node(k, 2 * i + 1, 2 * j);
      c[2] = pyramid_.node(k, 2 * i, 2 * j + 1);
      c[3] = pyramid_.node(k, 2 * i + 1, 2 * j + 1);
    }
    if (!descend(c, ux, uy, dx, dy)) return false;
    i = 2 * i + dx;
    j = 2 * j + dy;
  }
  const double p = texel_pdf(i, j);
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
  return texel_pdf(x, y);
}

double ProductSampler::texel_pdf(int x, int y) const {
  const int ci = x >> coarse_level_, cj = y >> coarse_level_;
  const double leaf = pyramid_.node(0, x, y);
  if (!(leaf > 0.0)) return 0.0;
  double q = 0.0;  // (product weight of the texel's nodes / their env sums) x total_
  const double pc = coarse_probability(ci, cj);
  if (pc > 0.0) {
    const double env_coarse = pyramid_.node(coarse_level_, ci, cj);
    if (!(env_coarse > 0.0)) return 0.0;
    q = pc * (leaf / env_coarse);
  }
  if (lobe_active_) {
    const double b = lobe_b(x, y);
    if (b > 0.0) {
      if (options_.lobe_descent) {
        const int l = lobe_level_;
        q += b * pyramid_.node(l, x >> l, y >> l) * lobe_path_probability(x, y) / total_;
      } else {
        q += b * leaf / total_;
      }
    }
  }
  const double p = q / env_.texel_solid_angle(x, y);
  return std::isfinite(p) ? p : 0.0;
}

}  // namespace envkit::render
