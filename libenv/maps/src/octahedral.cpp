#include <envkit/core/error.h>
#include <envkit/maps/octahedral.h>

#include <algorithm>
#include <cmath>

namespace envkit {

namespace {

/// Unit square [0,1]^2 -> unit direction in octahedron coordinates (pole +z_o).
Vec3 square_to_sphere(Vec2 p) {
  const double u = 2.0 * p.x - 1.0, v = 2.0 * p.y - 1.0;
  const double up = std::abs(u), vp = std::abs(v);
  // Signed distance from the diagonal |u| + |v| = 1 decides the hemisphere; r is the distance from the pole.
  const double signed_distance = 1.0 - (up + vp);
  const double r = 1.0 - std::abs(signed_distance);
  const double phi = (r == 0.0 ? 1.0 : (vp - up) / r + 1.0) * kPi / 4.0;
  const double z = std::copysign(1.0 - r * r, signed_distance);
  const double cos_phi = std::copysign(std::cos(phi), u), sin_phi = std::copysign(std::sin(phi), v);
  const double s = r * safe_sqrt(2.0 - r * r);
  return Vec3(cos_phi * s, sin_phi * s, z);
}

/// Inverse of square_to_sphere.
Vec2 sphere_to_square(const Vec3& d_in) {
  const Vec3 d = d_in.normalized();
  const double x = std::abs(d.x), y = std::abs(d.y), z = std::abs(d.z);
  // r = sqrt(1 - |z|), computed as sqrt((x^2 + y^2) / (1 + |z|)) to keep precision near the poles.
  const double r = std::sqrt((x * x + y * y) / (1.0 + z));
  const double a = std::max(x, y), b = std::min(x, y);
  double phi = a == 0.0 ? 0.0 : std::atan(b / a) * (2.0 / kPi);
  if (x < y) phi = 1.0 - phi;
  double v = phi * r, u = r - v;
  if (d.z < 0.0) {
    std::swap(u, v);
    u = 1.0 - u;
    v = 1.0 - v;
  }
  u = std::copysign(u, d.x);
  v = std::copysign(v, d.y);
  return Vec2(0.5 * (u + 1.0), 0.5 * (v + 1.0));
}

}  // namespace

Vec3 OctahedralMap::direction_from_unit(Vec2 p) {
  const Vec3 o = square_to_sphere(p);
  return Vec3(o.y, o.z, o.x);  // octahedron coordinates (x_o, y_o, z_o) = (Z, X, Y)
}

Vec2 OctahedralMap::unit_from_direction(const Vec3& dir) { return sphere_to_square(Vec3(dir.z, dir.x, dir.y)); }

OctahedralMap::OctahedralMap(int size) : Parameterization(size, size) {
  if (size <= 0) throw Error("octahedral map size must be positive");
}

std::string OctahedralMap::describe() const {
  return "octahedral " + std::to_string(width_) + "x" + std::to_string(height_) + " (equal-area, centre +Y)";
}

bool OctahedralMap::to_direction(Vec2 pos, Vec3& dir) const {
  dir = direction_from_unit(Vec2(pos.x / width_, pos.y / height_));
  return true;
}

Vec2 OctahedralMap::to_image(const Vec3& dir) const {
  const Vec2 p = unit_from_direction(dir);
  const double limit = std::nextafter(static_cast<double>(width_), 0.0);
  return Vec2(std::clamp(p.x * width_, 0.0, limit), std::clamp(p.y * height_, 0.0, limit));
}

double OctahedralMap::solid_angle(double x0, double y0, double x1, double y1) const {
  const double n = width_;
  const double w = std::clamp(x1, 0.0, n) - std::clamp(x0, 0.0, n);
  const double h = std::clamp(y1, 0.0, n) - std::clamp(y0, 0.0, n);
  return (w > 0.0 && h > 0.0) ? kFourPi * w * h / (n * n) : 0.0;
}

bool OctahedralMap::resolve_tap(int /*anchor_i*/, int /*anchor_j*/, int& i, int& j) const {
  // Crossing an edge lands on the mirror image across that edge's mid-point: (u, v) -> (-u, 1 - v).
  const int n = width_;
  for (int pass = 0; pass < 2; ++pass) {
    if (i < 0) {
      i = -1 - i;
      j = n - 1 - j;
    } else if (i >= n) {
      i = 2 * n - 1 - i;
      j = n - 1 - j;
    }
    if (j < 0) {
      j = -1 - j;
      i = n - 1 - i;
    } else if (j >= n) {
      j = 2 * n - 1 - j;
      i = n - 1 - i;
    }
  }
  i = std::clamp(i, 0, n - 1);
  j = std::clamp(j, 0, n - 1);
  return true;
}

}  // namespace envkit
