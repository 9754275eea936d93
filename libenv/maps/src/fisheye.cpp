#include <envkit/core/error.h>
#include <envkit/maps/fisheye.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace envkit {

FisheyeMap::FisheyeMap(int width, int height, const ViewParams& view) : RadialMap(width, height), view_(view) {
  if (width <= 0 || height <= 0) throw Error("a fisheye view needs a non-empty image");
  const double fov = view.fov_degrees;
  const double max_fov = view.lens == Lens::Orthographic ? 180.0 : 360.0;
  const bool open_max = view.lens == Lens::Stereographic;
  if (!(fov >= kMinFovDegrees) || fov > max_fov || (open_max && fov >= max_fov))
    throw Error("the field of view of a fisheye (" + lens_name(view.lens) + ") must be in [" +
                number_text(kMinFovDegrees) + ", " + std::to_string(int(max_fov)) + (open_max ? ")" : "]") +
                " degrees, not " + number_text(fov));
  half_ = 0.5 * fov * kPi / 180.0;
  switch (view.lens) {
    case Lens::Equidistant:
      k_ = half_;
      break;
    case Lens::Equisolid:
      k_ = std::sin(0.5 * half_);
      break;
    case Lens::Orthographic:
      k_ = std::sin(half_);
      break;
    case Lens::Stereographic:
      k_ = std::tan(0.5 * half_);
      break;
  }
  const ViewBasis b = view_basis(view);
  Disk d;
  d.cx = 0.5 * width;
  d.cy = 0.5 * height;
  d.radius = 0.5 * std::min(width, height);
  d.axis = b.forward;
  d.right = b.right;
  d.up = b.up;
  disks_.push_back(d);
}

std::string FisheyeMap::describe() const {
  std::ostringstream s;
  s.precision(4);
  const Vec3 f = disks_[0].axis;
  s << "fisheye " << width_ << "x" << height_ << " (" << lens_name(view_.lens) << ", " << view_.fov_degrees
    << " deg, forward " << f.x << "," << f.y << "," << f.z << ", roll " << view_.roll_degrees << ")";
  return s.str();
}

bool FisheyeMap::covers_sphere() const {
  return half_ >= kPi && (view_.lens == Lens::Equidistant || view_.lens == Lens::Equisolid);
}

Vec2 FisheyeMap::to_image(const Vec3& dir) const {
  const Disk& d = disks_[0];
  const Vec3 n = dir.normalized();
  const double theta = std::atan2(std::hypot(n ^ d.right, n ^ d.up), n ^ d.axis);
  if (theta > half_) return Vec2(-1.0, -1.0);
  return RadialMap::to_image(dir);
}

double FisheyeMap::polar_angle(double r) const {
  switch (view_.lens) {
    case Lens::Equidistant:
      return r * k_;
    case Lens::Equisolid:
      return 2.0 * safe_asin(r * k_);
    case Lens::Orthographic:
      return safe_asin(r * k_);
    case Lens::Stereographic:
      return 2.0 * std::atan(r * k_);
  }
  return 0.0;
}

double FisheyeMap::radius_of_angle(double theta) const {
  switch (view_.lens) {
    case Lens::Equidistant:
      return theta / k_;
    case Lens::Equisolid:
      return std::sin(0.5 * theta) / k_;
    case Lens::Orthographic:
      return theta >= 0.5 * kPi ? 1.0 / k_ : std::sin(theta) / k_;
    case Lens::Stereographic:
      return theta >= kPi ? 1e300 : std::tan(0.5 * theta) / k_;
  }
  return 0.0;
}

// (1 - cos theta) / r^2 = 2 sin^2(theta / 2) / r^2, in closed form per lens
// (finite at r = 0).
double FisheyeMap::cap_density(double r) const {
  switch (view_.lens) {
    case Lens::Equidistant:
      return equidistant_cap_density(r, k_);
    case Lens::Equisolid:
      return 2.0 * k_ * k_;
    case Lens::Orthographic: {
      const double c = safe_sqrt(1.0 - r * r * k_ * k_);
      return k_ * k_ / (1.0 + c);
    }
    case Lens::Stereographic:
      return 2.0 * k_ * k_ / (1.0 + r * r * k_ * k_);
  }
  return 0.0;
}

// theta'(r) sin(theta) / r.
double FisheyeMap::area_density(double r) const {
  switch (view_.lens) {
    case Lens::Equidistant:
      return equidistant_area_density(r, k_);
    case Lens::Equisolid:
      return 4.0 * k_ * k_;
    case Lens::Orthographic: {
      const double c = safe_sqrt(1.0 - r * r * k_ * k_);
      return c > 1e-12 ? k_ * k_ / c : k_ * k_ * 1e12;
    }
    case Lens::Stereographic: {
      const double q = 1.0 + r * r * k_ * k_;
      return 4.0 * k_ * k_ / (q * q);
    }
  }
  return 0.0;
}

}  // namespace envkit
