#include <envkit/env_sampling.h>
#include <envkit/latlong.h>
#include <envkit/octahedral.h>

#include <algorithm>
#include <cmath>

namespace envkit {

const char* method_name(SamplingMethod method) {
  switch (method) {
    case SamplingMethod::Cdf: return "cdf";
    case SamplingMethod::Alias: return "alias";
    case SamplingMethod::Hierarchical: return "hierarchical";
  }
  return "?";
}

SamplingMethod parse_method(const std::string& name) {
  if (name == "cdf") return SamplingMethod::Cdf;
  if (name == "alias") return SamplingMethod::Alias;
  if (name == "hierarchical" || name == "pyramid") return SamplingMethod::Hierarchical;
  throw Error("unknown sampling method '" + name + "' (expected cdf, alias or hierarchical)");
}

namespace {

bool finite_nonzero(const Vec3& d) {
  const double n2 = d.length2();
  return std::isfinite(n2) && n2 > 0.0;
}

}  // namespace

SphericalDistribution::RowBand SphericalDistribution::row_band(int j, int height) {
  const double theta0 = kPi * double(j) / height, theta1 = kPi * double(j + 1) / height;
  RowBand band;
  band.span = 2.0 * std::sin(0.5 * (theta1 + theta0)) * std::sin(0.5 * (theta1 - theta0));
  band.north = 2 * j + 1 <= height;  // the row's centre is at or above the equator
  if (band.north) {
    const double s = std::sin(0.5 * theta0);
    band.start = 2.0 * s * s;
  } else {
    const double c = std::cos(0.5 * theta1);
    band.start = 2.0 * c * c;
  }
  return band;
}

SphericalDistribution::SphericalDistribution(Kind grid, std::shared_ptr<const Distribution2D> distribution)
    : grid_(grid), distribution_(std::move(distribution)) {
  if (!distribution_) throw Error("spherical distribution: null distribution");
  if (grid_ != Kind::LatLong && grid_ != Kind::Octahedral)
    throw Error(std::string("spherical distribution: unsupported grid '") + kind_name(grid_) +
                "' (expected latlong or octahedral)");
  if (grid_ == Kind::Octahedral && width() != height())
    throw Error("spherical distribution: an octahedral grid must be square, got " + std::to_string(width()) + "x" +
                std::to_string(height()));
  if (grid_ == Kind::LatLong) {
    rows_.resize(std::size_t(height()));
    for (int y = 0; y < height(); ++y) rows_[std::size_t(y)] = row_band(y, height());
  }
}

double SphericalDistribution::texel_solid_angle(int x, int y) const {
  (void)x;
  const double W = width(), H = height();
  if (grid_ == Kind::Octahedral) return kFourPi / (W * H);
  return (kTwoPi / W) * rows_[std::size_t(std::clamp(y, 0, height() - 1))].span;
}

Vec3 SphericalDistribution::direction_in_texel(int x, int y, double fx, double fy) const {
  const double W = width();
  if (grid_ == Kind::Octahedral) {
    const Vec3 o = OctahedralMap::square_to_sphere(Vec2((x + fx) / W, (y + fy) / W));
    return Vec3(o.y, o.z, o.x);  // octahedron coordinates (x_o, y_o, z_o) = (Z, X, Y), as OctahedralMap
  }
  const double lon = kPi - kTwoPi * ((x + fx) / W);
  const RowBand& band = rows_[std::size_t(y)];
  // Uniform in solid angle inside the row: cos theta linear in fy.
  double from_pole = band.north ? band.start + fy * band.span : band.start + (1.0 - fy) * band.span;
  from_pole = std::clamp(from_pole, 0.0, 2.0);
  const double sin_theta = std::sqrt(std::max(0.0, from_pole * (2.0 - from_pole)));
  const double cos_theta = band.north ? 1.0 - from_pole : from_pole - 1.0;
  return Vec3(std::sin(lon) * sin_theta, cos_theta, std::cos(lon) * sin_theta);
}

void SphericalDistribution::locate(const Vec3& direction, int& x, int& y, double& fx, double& fy) const {
  const int W = width(), H = height();
  Vec3 d = finite_nonzero(direction) ? direction.normalized() : Vec3(0.0, 1.0, 0.0);
  if (grid_ == Kind::Octahedral) {
    const Vec2 q = OctahedralMap::sphere_to_square(Vec3(d.z, d.x, d.y));
    const Vec2 p(q.x * W, q.y * H);
    x = std::clamp(int(std::floor(p.x)), 0, W - 1);
    y = std::clamp(int(std::floor(p.y)), 0, H - 1);
    fx = std::clamp(p.x - x, 0.0, 1.0);
    fy = std::clamp(p.y - y, 0.0, 1.0);
    return;
  }
  const Vec2 uv = LatLongMap::uv_from_direction(d);
  x = std::clamp(int(uv.x * W), 0, W - 1);
  fx = std::clamp(uv.x * W - x, 0.0, 1.0);
  const double horizontal = std::hypot(d.x, d.z);
  const double theta = std::atan2(horizontal, d.y);
  y = std::clamp(int(theta / kPi * H), 0, H - 1);
  const RowBand& band = rows_[std::size_t(y)];
  // Distance from the nearer pole, 1 -+ cos theta, without cancellation: h^2 / (1 +- cos theta).
  const double from_pole = band.north ? (d.y > 0.0 ? horizontal * horizontal / (1.0 + d.y) : 1.0 - d.y)
                                      : (d.y < 0.0 ? horizontal * horizontal / (1.0 - d.y) : 1.0 + d.y);
  const double t = (from_pole - band.start) / band.span;
  fy = std::clamp(band.north ? t : 1.0 - t, 0.0, 1.0);
}

void SphericalDistribution::texel_of(const Vec3& direction, int& x, int& y) const {
  double fx = 0.0, fy = 0.0;
  locate(direction, x, y, fx, fy);
}

DirectionSample SphericalDistribution::sample(Vec2 u) const {
  const DistributionSample s = distribution_->sample(u);
  const double fx = sampling::clamp_offset(s.uv.x * width() - s.x);
  const double fy = sampling::clamp_offset(s.uv.y * height() - s.y);
  DirectionSample out;
  out.x = s.x;
  out.y = s.y;
  out.direction = direction_in_texel(s.x, s.y, fx, fy);
  out.pdf = s.pdf / (double(width()) * double(height()) * texel_solid_angle(s.x, s.y));
  return out;
}

double SphericalDistribution::pdf(const Vec3& direction) const {
  if (!finite_nonzero(direction)) return 0.0;
  int x = 0, y = 0;
  texel_of(direction, x, y);
  const Vec2 centre((x + 0.5) / width(), (y + 0.5) / height());
  return distribution_->pdf(centre) / (double(width()) * double(height()) * texel_solid_angle(x, y));
}

Vec2 SphericalDistribution::invert(const Vec3& direction) const {
  int x = 0, y = 0;
  double fx = 0.0, fy = 0.0;
  locate(direction, x, y, fx, fy);
  // Keep the position inside texel (x, y): fx = 1 would name the next texel.
  fx = sampling::clamp_offset(fx);
  fy = sampling::clamp_offset(fy);
  return distribution_->invert(Vec2((x + fx) / width(), (y + fy) / height()));
}

}  // namespace envkit
