#include <envkit/maps/angular.h>

#include <cmath>

namespace envkit {

AngularMap::AngularMap(int width, int height) : RadialMap(width, height) {
  disks_.push_back(
      Disk{0.5 * width, 0.5 * height, 0.5 * std::min(width, height), Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, 1, 0)});
}

std::string AngularMap::describe() const {
  return "angular " + std::to_string(width_) + "x" + std::to_string(height_) + " (light probe, centre +Z)";
}

double AngularMap::polar_angle(double r) const { return kPi * std::clamp(r, 0.0, 1.0); }
double AngularMap::radius_of_angle(double theta) const { return std::clamp(theta, 0.0, kPi) / kPi; }

// (1 - cos(pi r)) / r^2 = 2 sin^2(pi r / 2) / r^2, written to stay accurate near r = 0.
double AngularMap::cap_density(double r) const {
  if (r < 1e-4) return 0.5 * kPi * kPi * (1.0 - kPi * kPi * r * r / 12.0);
  const double s = std::sin(0.5 * kPi * r) / r;
  return 2.0 * s * s;
}

// pi sin(pi r) / r, which tends to pi^2 at the centre and to 0 at the rim.
double AngularMap::area_density(double r) const {
  if (r < 1e-6) return kPi * kPi;
  return kPi * std::sin(kPi * std::min(r, 1.0)) / r;
}

}  // namespace envkit
