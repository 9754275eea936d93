// One texel of a map set to a value over a constant floor.
#include <envkit/core/error.h>
#include <envkit/probes.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace envkit::probes {

TexelProbe::TexelProbe(const Parameterization& map, int i, int j, Vec3 value, Vec3 floor)
    : map_(map.clone()), i_(i), j_(j), value_(value), floor_(floor) {
  if (i < 0 || j < 0 || i >= map.width() || j >= map.height())
    throw Error("texel probe: texel " + std::to_string(i) + "," + std::to_string(j) + " is outside the " +
                std::to_string(map.width()) + "x" + std::to_string(map.height()) + " map");
  if (!valid_radiance(value) || !valid_radiance(floor)) throw Error("texel probe: radiances must be finite and >= 0");
  Feature f;
  f.solid_angle = map.texel_solid_angle(i, j);
  // Centre direction; a texel cut by a mirror ball's rim may have no data at its centre: take any point that has.
  bool has_centre = map.to_direction(Vec2(i + 0.5, j + 0.5), f.centre);
  for (int s = 0; s < 64 && !has_centre; ++s)
    has_centre = map.to_direction(Vec2(i + (s % 8 + 0.5) / 8.0, j + (s / 8 + 0.5) / 8.0), f.centre);
  if (!(f.solid_angle > 0.0) || !has_centre)
    throw Error("texel probe: texel " + std::to_string(i) + "," + std::to_string(j) + " holds no data");
  // Bounding cap: the farthest of a dense ring of points just inside the texel's edges, with a margin
  // (edges of spherical cells are not straight, so the sampled maximum may fall a little short).
  double bound = 0.0;
  constexpr int kSteps = 16;
  constexpr double kInset = 1e-6;
  for (int s = 0; s <= kSteps; ++s) {
    const double t = kInset + (1.0 - 2.0 * kInset) * s / kSteps;
    const Vec2 ring[4] = {Vec2(i + t, j + kInset), Vec2(i + t, j + 1 - kInset), Vec2(i + kInset, j + t),
                          Vec2(i + 1 - kInset, j + t)};
    for (const Vec2& p : ring) {
      Vec3 d;
      if (map.to_direction(p, d)) bound = std::max(bound, angle_between(f.centre, d));
    }
  }
  f.bound = std::min(kPi, bound * 1.05 + 1e-9);
  f.is_disk = false;
  f.excess = value - floor;
  f.leaf_radius = f.bound / 16.0;
  features_.push_back(f);
}

std::string TexelProbe::describe() const {
  std::ostringstream s;
  s << "texel: (" << i_ << ", " << j_ << ") of " << map_->describe() << " = (" << value_.x << ", " << value_.y << ", "
    << value_.z << ") over floor (" << floor_.x << ", " << floor_.y << ", " << floor_.z << ")";
  return s.str();
}

bool TexelProbe::in_feature(std::size_t, const Vec3& dir) const {
  const Vec2 p = map_->to_image(dir);
  return std::floor(p.x) == i_ && std::floor(p.y) == j_;
}

bool TexelProbe::integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const {
  integral = floor_ * latlong_rect_solid_angle(u0, u1, v0, v1);
  return true;
}

Vec3 TexelProbe::total_power() const {
  const double omega = features_[0].solid_angle;
  return value_ * omega + floor_ * (kFourPi - omega);
}

}  // namespace envkit::probes
