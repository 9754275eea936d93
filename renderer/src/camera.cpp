#include <envkit/core/error.h>
#include <envkit/render/camera.h>

#include <cmath>

namespace envkit::render {

Camera::Camera(const Vec3& position, const Vec3& look_at, const Vec3& up, double fov_deg, int width, int height)
    : position_(position), width_(width), height_(height) {
  const Vec3 view = look_at - position;
  if (!(view.length() > 0.0)) throw Error("camera: position and look_at coincide");
  if (!(fov_deg > 0.0 && fov_deg < 180.0)) throw Error("camera: fov must be in (0, 180) degrees");
  if (width < 1 || height < 1) throw Error("camera: resolution must be positive");
  forward_ = view.normalized();
  Vec3 right = forward_ % up;  // forward x up: the viewer's right
  if (!(right.length() > 1e-9 * up.length()) || !(up.length() > 0.0))
    throw Error("camera: up is zero or parallel to the view direction");
  right_ = right.normalized();
  up_ = (right_ % forward_).normalized();
  tan_half_ = std::tan(0.5 * fov_deg * kPi / 180.0);
}

Ray Camera::generate(double px, double py) const {
  const double aspect = double(width_) / double(height_);
  const double sx = (2.0 * px / width_ - 1.0) * tan_half_ * aspect;
  const double sy = (1.0 - 2.0 * py / height_) * tan_half_;
  return Ray{position_, (forward_ + right_ * sx + up_ * sy).normalized()};
}

}  // namespace envkit::render
