#include <envkit/maps/paraboloid.h>

#include <cmath>

namespace envkit {

DualParaboloidMap::DualParaboloidMap(int width, int height) : RadialMap(width, height) {
  const double half = 0.5 * width;
  const double radius = 0.5 * std::min(half, static_cast<double>(height));
  disks_.push_back(Disk{0.5 * half, 0.5 * height, radius, Vec3(0, 0, 1), Vec3(-1, 0, 0), Vec3(0, 1, 0)});
  disks_.push_back(Disk{1.5 * half, 0.5 * height, radius, Vec3(0, 0, -1), Vec3(1, 0, 0), Vec3(0, 1, 0)});
  tap_cell_ = -1;  // taps beyond a disk's rim continue into the other hemisphere
}

std::string DualParaboloidMap::describe() const {
  return "paraboloid " + std::to_string(width_) + "x" + std::to_string(height_) + " (left +Z, right -Z)";
}

// The formula extends beyond the rim (theta > pi/2 for r > 1), which resolve_tap uses to re-project.
double DualParaboloidMap::polar_angle(double r) const { return 2.0 * std::atan(std::max(r, 0.0)); }
double DualParaboloidMap::radius_of_angle(double theta) const {
  return std::tan(0.5 * std::clamp(theta, 0.0, kPi / 2));
}
// 1 - cos(2 atan r) = 2 r^2 / (1 + r^2).
double DualParaboloidMap::cap_density(double r) const { return 2.0 / (1.0 + r * r); }

bool DualParaboloidMap::resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const {
  const int k = disk_at(Vec2(anchor_i + 0.5, anchor_j + 0.5));
  if (k < 0) return clamp_tap(i, j);
  const Disk& d = disks_[k];
  const double x = (i + 0.5 - d.cx) / d.radius, y = (d.cy - (j + 0.5)) / d.radius;
  const double r = std::sqrt(x * x + y * y);
  if (r <= 1.0 && i >= 0 && j >= 0 && i < width_ && j < height_) return true;
  // Continue the anchor's paraboloid past its rim into the other hemisphere.
  const double theta = polar_angle(r);
  const Vec3 dir = std::cos(theta) * d.axis + std::sin(theta) * (x * d.right + y * d.up) / r;
  const Vec2 p = to_image(dir);
  i = std::clamp(static_cast<int>(p.x), 0, width_ - 1);
  j = std::clamp(static_cast<int>(p.y), 0, height_ - 1);
  return true;
}

}  // namespace envkit
