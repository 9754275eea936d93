// L = constant.
#include <envkit/core/error.h>
#include <envkit/probes.h>

#include <cmath>
#include <sstream>

namespace envkit::probes {

ConstantProbe::ConstantProbe(Vec3 radiance) : radiance_(radiance) {
  if (!valid_radiance(radiance)) throw Error("constant probe: radiance must be finite and >= 0");
}

std::string ConstantProbe::describe() const {
  std::ostringstream s;
  s << "constant: L = (" << radiance_.x << ", " << radiance_.y << ", " << radiance_.z << ")";
  return s.str();
}

bool ConstantProbe::integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const {
  integral = radiance_ * latlong_rect_solid_angle(u0, u1, v0, v1);
  return true;
}

Vec3 ConstantProbe::total_power() const { return radiance_ * kFourPi; }

std::optional<Vec3> ConstantProbe::upward_irradiance() const { return radiance_ * kPi; }

}  // namespace envkit::probes
