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
  orthographic_ = view.lens == Lens::Orthographic;
  const auto check_fov = [&](double fov, const char* what) {
    // A pinhole sees less than a half-space; the orthographic projection all of it.
    if (!(fov >= kMinFovDegrees && (orthographic_ ? fov <= 180.0 : fov < 180.0)))
      throw Error(std::string("a perspective ") + what + " must be in [" + number_text(kMinFovDegrees) +
                  (orthographic_ ? ", 180]" : ", 180)") + " degrees, not " + number_text(fov));
  };
  check_fov(view.fov_degrees, "field of view");
  if (view.fov_v_degrees != 0.0) check_fov(view.fov_v_degrees, "vertical field of view");
  // Half-extent of the image plane for a full angle: tan (pinhole) or sin (orthographic) of its half.
  const auto extent = [&](double fov) {
    const double h = 0.5 * fov * kPi / 180.0;
    return orthographic_ ? std::sin(h) : std::tan(h);
  };
  const double t = extent(view.fov_degrees);
  const double aspect = double(width) / height;
  if (view.fov_v_degrees > 0.0) {
    tx_ = t;
    ty_ = extent(view.fov_v_degrees);
  } else {
    tx_ = view.fov_axis == FovAxis::Horizontal ? t : t * aspect;
    ty_ = view.fov_axis == FovAxis::Horizontal ? t / aspect : t;
  }
  if (orthographic_ && tx_ * tx_ + ty_ * ty_ > 1.0 + 1e-12)
    throw Error("an orthographic view's corners leave the hemisphere: sin^2(hfov/2) + sin^2(vfov/2) is " +
                number_text(tx_ * tx_ + ty_ * ty_) + ", above 1 (narrow the field of view or the aspect)");
}

namespace {

/// Solid angle of the orthographic view's plane rectangle [0, a] x [0, b] (signed, odd in a and b): G(a, b) of
/// perspective.h.
double orthographic_rect_solid_angle(double a, double b) {
  const double s = safe_sqrt(1.0 - a * a - b * b);
  const double ca = safe_sqrt(1.0 - a * a), cb = safe_sqrt(1.0 - b * b);
  const double ta = ca > 0.0 ? safe_asin(b / ca) : 0.0, tb = cb > 0.0 ? safe_asin(a / cb) : 0.0;
  return a * ta + b * tb - std::atan2(a * b, s);
}

}  // namespace

std::string PerspectiveMap::describe() const {
  std::ostringstream s;
  s.precision(4);
  const auto full_angle = [&](double t) { return 2.0 * (orthographic_ ? std::asin(t) : std::atan(t)) * 180.0 / kPi; };
  s << (orthographic_ ? "orthographic perspective " : "perspective ") << width_ << "x" << height_ << " ("
    << full_angle(tx_) << " x " << full_angle(ty_) << " deg, forward " << basis_.forward.x << "," << basis_.forward.y
    << "," << basis_.forward.z << ", roll " << view_.roll_degrees << ")";
  return s.str();
}

bool PerspectiveMap::to_direction(Vec2 pos, Vec3& dir) const {
  const double a = (2.0 * pos.x / width_ - 1.0) * tx_, b = (1.0 - 2.0 * pos.y / height_) * ty_;
  if (orthographic_)
    dir = (safe_sqrt(1.0 - a * a - b * b) * basis_.forward + a * basis_.right + b * basis_.up).normalized();
  else
    dir = (basis_.forward + a * basis_.right + b * basis_.up).normalized();
  return true;
}

Vec2 PerspectiveMap::to_image(const Vec3& dir) const {
  double z = dir ^ basis_.forward;
  if (!(z > 0.0)) return Vec2(-1.0, -1.0);
  if (orthographic_) z = dir.length();  // the plane coordinates of the unit direction
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
  if (orthographic_)
    return orthographic_rect_solid_angle(a1, b1) - orthographic_rect_solid_angle(a0, b1) -
           orthographic_rect_solid_angle(a1, b0) + orthographic_rect_solid_angle(a0, b0);
  return CubeMap::face_rect_solid_angle(a0, b0, a1, b1);
}

// d(omega)/dA on the unit-distance plane is 1 / (1 + a^2 + b^2)^(3/2), times
// the pixel's plane area.
double PerspectiveMap::solid_angle_density(Vec2 pos) const {
  if (pos.x < 0.0 || pos.y < 0.0 || pos.x > width_ || pos.y > height_) return 0.0;
  const double a = (2.0 * pos.x / width_ - 1.0) * tx_, b = (1.0 - 2.0 * pos.y / height_) * ty_;
  const double pixel_area = (2.0 * tx_ / width_) * (2.0 * ty_ / height_);
  if (orthographic_) return pixel_area / std::max(std::sqrt(std::max(0.0, 1.0 - a * a - b * b)), 1e-12);
  const double len2 = 1.0 + a * a + b * b;
  return pixel_area / (len2 * std::sqrt(len2));
}

double PerspectiveMap::view_solid_angle() const {
  if (orthographic_) return 4.0 * orthographic_rect_solid_angle(tx_, ty_);
  return 4.0 * std::asin(std::sin(std::atan(tx_)) * std::sin(std::atan(ty_)));
}

}  // namespace envkit
