#include <envkit/core/error.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/perspective.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace envkit {

PerspectiveMap::PerspectiveMap(int width, int height, const ViewParams& view)
    : Parameterization(width, height), view_(view), basis_(view_basis(view)) {
  if (width <= 0 || height <= 0) throw Error("a perspective view needs a non-empty image");
  if (!(view.fov_degrees >= kMinFovDegrees && view.fov_degrees < 180.0))
    throw Error("a perspective field of view must be in [" + number_text(kMinFovDegrees) + ", 180) degrees, not " +
                number_text(view.fov_degrees));
  const double t = std::tan(0.5 * view.fov_degrees * kPi / 180.0);
  const double aspect = double(width) / height;
  tx_ = view.fov_axis == FovAxis::Horizontal ? t : t * aspect;
  ty_ = view.fov_axis == FovAxis::Horizontal ? t / aspect : t;
}

std::string PerspectiveMap::describe() const {
  std::ostringstream s;
  s.precision(4);
  s << "perspective " << width_ << "x" << height_ << " (" << 2.0 * std::atan(tx_) * 180.0 / kPi << " x "
    << 2.0 * std::atan(ty_) * 180.0 / kPi << " deg, forward " << basis_.forward.x << "," << basis_.forward.y << ","
    << basis_.forward.z << ", roll " << view_.roll_degrees << ")";
  return s.str();
}

bool PerspectiveMap::to_direction(Vec2 pos, Vec3& dir) const {
  const double a = (2.0 * pos.x / width_ - 1.0) * tx_, b = (1.0 - 2.0 * pos.y / height_) * ty_;
  dir = (basis_.forward + a * basis_.right + b * basis_.up).normalized();
  return true;
}

Vec2 PerspectiveMap::to_image(const Vec3& dir) const {
  const double z = dir ^ basis_.forward;
  if (!(z > 0.0)) return Vec2(-1.0, -1.0);
  const double a = (dir ^ basis_.right) / z, b = (dir ^ basis_.up) / z;
  const double x = 0.5 * (a / tx_ + 1.0) * width_, y = 0.5 * (1.0 - b / ty_) * height_;
  // Far outside: keep the numbers finite and outside.
  return Vec2(std::clamp(x, -1.0, width_ + 1.0), std::clamp(y, -1.0, height_ + 1.0));
}

double PerspectiveMap::solid_angle(double x0, double y0, double x1, double y1) const {
  x0 = std::max(x0, 0.0);
  y0 = std::max(y0, 0.0);
  x1 = std::min(x1, double(width_));
  y1 = std::min(y1, double(height_));
  if (x1 <= x0 || y1 <= y0) return 0.0;
  const double a0 = (2.0 * x0 / width_ - 1.0) * tx_, a1 = (2.0 * x1 / width_ - 1.0) * tx_;
  const double b0 = (1.0 - 2.0 * y1 / height_) * ty_, b1 = (1.0 - 2.0 * y0 / height_) * ty_;
  return CubeMap::face_rect_solid_angle(a0, b0, a1, b1);
}

// d(omega)/dA on the unit-distance plane is 1 / (1 + a^2 + b^2)^(3/2), times
// the pixel's plane area.
double PerspectiveMap::solid_angle_density(Vec2 pos) const {
  if (pos.x < 0.0 || pos.y < 0.0 || pos.x > width_ || pos.y > height_) return 0.0;
  const double a = (2.0 * pos.x / width_ - 1.0) * tx_, b = (1.0 - 2.0 * pos.y / height_) * ty_;
  const double len2 = 1.0 + a * a + b * b;
  return (2.0 * tx_ / width_) * (2.0 * ty_ / height_) / (len2 * std::sqrt(len2));
}

double PerspectiveMap::view_solid_angle() const {
  return 4.0 * std::asin(std::sin(std::atan(tx_)) * std::sin(std::atan(ty_)));
}

}  // namespace envkit
