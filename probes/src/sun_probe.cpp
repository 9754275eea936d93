// A sun disk over a uniform sky.
#include <envkit/core/error.h>
#include <envkit/probes.h>

#include <cmath>
#include <sstream>

namespace envkit::probes {

SunProbe::SunProbe(Vec3 direction, double alpha, Vec3 sun, Vec3 sky) : alpha_(alpha), sun_(sun), sky_(sky) {
  const double len = direction.length();
  if (!std::isfinite(len) || len <= 0.0) throw Error("sun probe: direction must be a non-zero vector");
  if (!(alpha > 0.0) || alpha > 0.5 * kPi) throw Error("sun probe: radius must be in (0, 90] degrees");
  if (!valid_radiance(sun) || !valid_radiance(sky)) throw Error("sun probe: radiances must be finite and >= 0");
  Feature f;
  f.centre = direction / len;
  f.bound = alpha;
  f.is_disk = true;
  f.solid_angle = cap_solid_angle(alpha);
  f.excess = sun - sky;
  f.leaf_radius = alpha / 16.0;
  features_.push_back(f);
}

std::string SunProbe::describe() const {
  const Vec3& d = direction();
  std::ostringstream s;
  s << "sun: radius " << alpha_ * 180.0 / kPi << " deg, elevation "
    << std::asin(std::clamp(d.y, -1.0, 1.0)) * 180.0 / kPi << " deg, azimuth " << std::atan2(d.x, d.z) * 180.0 / kPi
    << " deg, L = (" << sun_.x << ", " << sun_.y << ", " << sun_.z << ") over sky (" << sky_.x << ", " << sky_.y << ", "
    << sky_.z << ")";
  return s.str();
}

bool SunProbe::integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const {
  integral = sky_ * latlong_rect_solid_angle(u0, u1, v0, v1);  // the background only; the disk is a feature
  return true;
}

Vec3 SunProbe::total_power() const {
  const double omega = features_[0].solid_angle;
  return sun_ * omega + sky_ * (kFourPi - omega);
}

std::optional<Vec3> SunProbe::upward_irradiance() const {
  // The cosine-weighted integral of a cap about its axis is pi sin^2(alpha); projected onto +Y it scales by
  // the axis' y, as long as the whole cap is on one side of the horizon.
  const double elevation = std::asin(std::clamp(direction().y, -1.0, 1.0));
  if (std::abs(elevation) < alpha_) return std::nullopt;
  const double s = std::sin(alpha_);
  const double disk = elevation > 0.0 ? kPi * s * s * direction().y : 0.0;
  return sky_ * kPi + (sun_ - sky_) * disk;
}

}  // namespace envkit::probes
