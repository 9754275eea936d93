#include <envkit/core/error.h>
#include <envkit/maps/mirrorball.h>

#include <cmath>
#include <sstream>

namespace envkit {

MirrorBallMap::MirrorBallMap(int width, int height)
    : MirrorBallMap(width, height, 0.5 * width, 0.5 * height, 0.5 * std::min(width, height)) {}

MirrorBallMap::MirrorBallMap(int width, int height, double cx, double cy, double radius) : RadialMap(width, height) {
  if (!(radius > 0.0) || !std::isfinite(cx) || !std::isfinite(cy))
    throw Error("mirror ball radius must be positive and its centre finite");
  disks_.push_back(Disk{cx, cy, radius, Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, 1, 0)});
}

std::string MirrorBallMap::describe() const {
  std::ostringstream s;
  const Disk& d = disks_[0];
  s << "mirrorball " << width_ << "x" << height_ << ", ball centre (" << d.cx << ", " << d.cy << ") radius " << d.radius
    << " px";
  return s.str();
}

double MirrorBallMap::polar_angle(double r) const { return 2.0 * std::asin(std::clamp(r, 0.0, 1.0)); }
double MirrorBallMap::radius_of_angle(double theta) const { return std::sin(0.5 * std::clamp(theta, 0.0, kPi)); }
// 1 - cos(2 asin r) = 2 r^2: the mirror ball is equal-area.
double MirrorBallMap::cap_density(double /*r*/) const { return 2.0; }

}  // namespace envkit
