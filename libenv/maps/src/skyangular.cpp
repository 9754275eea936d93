#include <envkit/maps/skyangular.h>

#include <algorithm>
#include <cmath>

namespace envkit {

namespace {
constexpr double kHorizon = 0.5 * kPi;  // the zenith angle on the rim
}  // namespace

SkyAngularMap::SkyAngularMap(int width, int height) : RadialMap(width, height) {
  disks_.push_back(
      Disk{0.5 * width, 0.5 * height, 0.5 * std::min(width, height), Vec3(0, 1, 0), Vec3(-1, 0, 0), Vec3(0, 0, -1)});
}

std::string SkyAngularMap::describe() const {
  return "skyangular " + std::to_string(width_) + "x" + std::to_string(height_) +
         " (upper hemisphere, zenith at the centre, right -X, up -Z)";
}

Vec2 SkyAngularMap::to_image(const Vec3& dir) const {
  if (dir.y < 0.0) return Vec2(-1.0, -1.0);
  return RadialMap::to_image(dir);
}

double SkyAngularMap::polar_angle(double r) const { return kHorizon * std::clamp(r, 0.0, 1.0); }
double SkyAngularMap::radius_of_angle(double theta) const { return std::clamp(theta, 0.0, kHorizon) / kHorizon; }

double SkyAngularMap::cap_density(double r) const { return equidistant_cap_density(r, kHorizon); }
double SkyAngularMap::area_density(double r) const { return equidistant_area_density(r, kHorizon); }

}  // namespace envkit
