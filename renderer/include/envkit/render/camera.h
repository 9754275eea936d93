#pragma once
/// @file camera.h
/// Pinhole look-at camera. World frame: envkit's (+Y up, right-handed). fov is the VERTICAL field of view in
/// degrees; the image has `width` x `height` pixels, pixel (x, y) covers [x, x+1) x [y, y+1) with row 0 at the
/// top. Image x grows to the camera's right = forward x up.
#include <envkit/core/vec.h>

namespace envkit::render {

struct Ray {
  Vec3 origin;
  Vec3 direction;  ///< unit
};

class Camera {
 public:
  Camera() = default;
  /// Throws Error when position == look_at, up is parallel to the view direction, fov is not in (0, 180) or the
  /// resolution is not positive.
  Camera(const Vec3& position, const Vec3& look_at, const Vec3& up, double fov_deg, int width, int height);

  /// Primary ray through the continuous image position (px, py) (pixels).
  Ray generate(double px, double py) const;

  const Vec3& position() const { return position_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  Vec3 position_{0, 0, 0};
  Vec3 forward_{0, 0, 1}, right_{-1, 0, 0}, up_{0, 1, 0};
  double tan_half_ = 1.0;
  int width_ = 1, height_ = 1;
};

}  // namespace envkit::render
