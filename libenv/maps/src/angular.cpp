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

double AngularMap::cap_density(double r) const { return equidistant_cap_density(r, kPi); }
double AngularMap::area_density(double r) const { return equidistant_area_density(r, kPi); }

}  // namespace envkit
