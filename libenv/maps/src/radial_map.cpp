#include <envkit/core/gauss_legendre.h>
#include <envkit/maps/radial_map.h>
#include <envkit/maps/view.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace envkit {

double equidistant_cap_density(double r, double k) {
  if (r < 1e-8) return 0.5 * k * k;
  const double s = std::sin(0.5 * r * k);
  return 2.0 * s * s / (r * r);
}

double equidistant_area_density(double r, double k) { return r < 1e-8 ? k * k : k * std::sin(r * k) / r; }

bool RadialMap::same_grid(const Parameterization& other) const {
  if (!same_kind_and_size(other)) return false;
  // Disks alone do not tell a fisheye's lens and field of view.
  const ViewParams *a = view(), *b = other.view();
  if ((a == nullptr) != (b == nullptr) || (a && !(*a == *b))) return false;
  const auto& o = static_cast<const RadialMap&>(other).disks_;
  const auto same_vec = [](const Vec3& a, const Vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; };
  return std::equal(disks_.begin(), disks_.end(), o.begin(), o.end(), [&](const Disk& a, const Disk& b) {
    return a.cx == b.cx && a.cy == b.cy && a.radius == b.radius && same_vec(a.axis, b.axis) &&
           same_vec(a.right, b.right) && same_vec(a.up, b.up);
  });
}

int RadialMap::disk_at(Vec2 pos) const {
  for (std::size_t k = 0; k < disks_.size(); ++k) {
    const Disk& d = disks_[k];
    const double x = (pos.x - d.cx) / d.radius, y = (d.cy - pos.y) / d.radius;
    if (x * x + y * y <= 1.0) return static_cast<int>(k);
  }
  return -1;
}

int RadialMap::disk_for_direction(const Vec3& dir) const {
  if (disks_.size() < 2) return 0;
  return (dir ^ disks_[0].axis) >= 0.0 ? 0 : 1;
}

bool RadialMap::covered_point(int i, int j, Vec2& pos) const {
  pos = Vec2(i + 0.5, j + 0.5);
  if (disk_at(pos) >= 0) return true;
  // The texel's point nearest to a disk centre is covered if any point of the texel is.
  for (const Disk& d : disks_) {
    const double e = 1e-9;
    pos = Vec2(std::clamp(d.cx, i + e, i + 1 - e), std::clamp(d.cy, j + e, j + 1 - e));
    if (disk_at(pos) >= 0) return true;
  }
  return false;
}

double RadialMap::solid_angle_density(Vec2 pos) const {
  const int k = disk_at(pos);
  if (k < 0) return 0.0;
  const Disk& d = disks_[k];
  const double x = (pos.x - d.cx) / d.radius, y = (d.cy - pos.y) / d.radius;
  return area_density(std::sqrt(x * x + y * y)) / (d.radius * d.radius);
}

bool RadialMap::to_direction(Vec2 pos, Vec3& dir) const {
  const int k = disk_at(pos);
  if (k < 0) return false;
  const Disk& d = disks_[k];
  const double x = (pos.x - d.cx) / d.radius, y = (d.cy - pos.y) / d.radius;
  const double r = std::sqrt(x * x + y * y);
  const double theta = polar_angle(std::min(r, 1.0));
  const Vec3 radial = r > 0.0 ? (x * d.right + y * d.up) / r : d.right;
  dir = (std::cos(theta) * d.axis + std::sin(theta) * radial).normalized();
  return true;
}

Vec2 RadialMap::to_image(const Vec3& dir_in) const {
  const Vec3 dir = dir_in.normalized();
  const Disk& d = disks_[disk_for_direction(dir)];
  const double px = dir ^ d.right, py = dir ^ d.up;
  const double lateral = std::hypot(px, py);
  const double theta = std::atan2(lateral, dir ^ d.axis);
  const double r = radius_of_angle(theta);
  // Straight behind the axis (lateral == 0, theta == pi) is the rim, a single direction: we use the rim point
  // to the right of the centre. On the axis itself r == 0 and the choice does not matter.
  const double ux = lateral > 0.0 ? px / lateral : 1.0, uy = lateral > 0.0 ? py / lateral : 0.0;
  // Stay a hair inside the disk so the position is covered.
  const double rr = std::min(r, 1.0 - 1e-12) * d.radius;
  return Vec2(d.cx + rr * ux, d.cy - rr * uy);
}

// Integral of G dphi along the straight edge a -> b in normalized disk coordinates.
double RadialMap::edge_integral(double ax, double ay, double bx, double by) const {
  const double cross = ax * by - ay * bx;
  if (cross == 0.0) return 0.0;  // radial edge: dphi = 0
  const double dx = bx - ax, dy = by - ay;
  // Split t in [0, 1] where the edge crosses the rim |a + t d| = 1.
  const double qa = dx * dx + dy * dy, qb = 2.0 * (ax * dx + ay * dy), qc = ax * ax + ay * ay - 1.0;
  std::array<double, 4> cuts{0.0, 1.0, 1.0, 1.0};
  int ncuts = 1;
  const double disc = qb * qb - 4.0 * qa * qc;
  if (qa > 0.0 && disc > 0.0) {
    const double s = std::sqrt(disc);
    for (double t : {(-qb - s) / (2.0 * qa), (-qb + s) / (2.0 * qa)})
      if (t > 0.0 && t < 1.0) cuts[ncuts++] = t;
  }
  cuts[ncuts++] = 1.0;
  const double g_rim = 1.0 - std::cos(polar_angle(1.0));
  double total = 0.0;
  for (int k = 0; k + 1 < ncuts; ++k) {
    const double t0 = cuts[k], t1 = cuts[k + 1];
    if (t1 <= t0) continue;
    const double tm = 0.5 * (t0 + t1);
    const double mx = ax + tm * dx, my = ay + tm * dy;
    if (mx * mx + my * my >= 1.0) {
      // Outside the disk G is constant: G(1) times the angle swept from p(t0) to p(t1).
      const double px0 = ax + t0 * dx, py0 = ay + t0 * dy, px1 = ax + t1 * dx, py1 = ay + t1 * dy;
      total += g_rim * std::atan2(px0 * py1 - py0 * px1, px0 * px1 + py0 * py1);
      continue;
    }
    // Inside: cross * integral of cap_density(r) / 1 dt, since G / r^2 = cap_density(r). Split long pieces so
    // the 8-point rule stays exact to round-off for these analytic integrands.
    const int pieces = std::max(1, static_cast<int>(std::ceil((t1 - t0) * std::sqrt(qa) / 0.125)));
    const double h = (t1 - t0) / pieces;
    double sum = 0.0;
    for (int p = 0; p < pieces; ++p)
      detail::for_nodes(t0 + p * h, t0 + (p + 1) * h, 8, [&](double t, double w) {
        const double x = ax + t * dx, y = ay + t * dy;
        sum += w * cap_density(std::min(std::sqrt(x * x + y * y), 1.0));
      });
    total += cross * sum;
  }
  return total;
}

double RadialMap::disk_solid_angle(const Disk& d, double x0, double y0, double x1, double y1) const {
  // Normalized corners; image y grows downwards, normalized y upwards, which reverses orientation: abs at the end.
  const double ax = (x0 - d.cx) / d.radius, bx = (x1 - d.cx) / d.radius;
  const double ay = (d.cy - y0) / d.radius, by = (d.cy - y1) / d.radius;
  // Rectangles entirely outside the disk see nothing.
  const double nearest_x = std::clamp(0.0, std::min(ax, bx), std::max(ax, bx));
  const double nearest_y = std::clamp(0.0, std::min(ay, by), std::max(ay, by));
  if (nearest_x * nearest_x + nearest_y * nearest_y >= 1.0) return 0.0;
  const double sum = edge_integral(ax, ay, bx, ay) + edge_integral(bx, ay, bx, by) + edge_integral(bx, by, ax, by) +
                     edge_integral(ax, by, ax, ay);
  return std::abs(sum);
}

double RadialMap::solid_angle(double x0, double y0, double x1, double y1) const {
  x0 = std::max(x0, 0.0);
  y0 = std::max(y0, 0.0);
  x1 = std::min(x1, static_cast<double>(width_));
  y1 = std::min(y1, static_cast<double>(height_));
  if (x1 <= x0 || y1 <= y0) return 0.0;
  double total = 0.0;
  for (const Disk& d : disks_) total += disk_solid_angle(d, x0, y0, x1, y1);
  return total;
}

}  // namespace envkit
