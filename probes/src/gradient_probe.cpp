// Sky gradients L = base + gain y^2 and L = base + gain max(y, 0).
#include <envkit/core/error.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace envkit::probes {

GradientProbe::GradientProbe(Vec3 base, Vec3 gain, Form form) : base_(base), gain_(gain), form_(form) {
  // Both forms take values in [base, base + gain]: radiance stays >= 0 iff base and base + gain are.
  if (!valid_radiance(base) || !valid_radiance(base + gain))
    throw Error("gradient probe: base and base + gain must be finite and >= 0");
}

std::string GradientProbe::describe() const {
  std::ostringstream s;
  s << "gradient: L = (" << base_.x << ", " << base_.y << ", " << base_.z << ") + (" << gain_.x << ", " << gain_.y
    << ", " << gain_.z << ")" << (form_ == Form::Quadratic ? " y^2" : " max(y, 0)");
  return s.str();
}

Vec3 GradientProbe::background(const Vec3& dir) const {
  const double t = form_ == Form::Quadratic ? dir.y * dir.y : std::max(dir.y, 0.0);
  return base_ + gain_ * t;
}

bool GradientProbe::background_may_vary(const Vec3& dir, double radius) const {
  // max(y, 0) has a kink on the horizon: refine cells that reach it so the sampled integral stays accurate.
  return form_ == Form::UpperLinear && std::abs(std::asin(std::clamp(dir.y, -1.0, 1.0))) < radius;
}

bool GradientProbe::integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const {
  const double dphi = kTwoPi * (u1 - u0);
  if (!(dphi > 0.0) || !(v1 > v0)) {
    integral = Vec3(0.0);
    return true;
  }
  const double theta0 = LatLongMap::polar_angle(v0), theta1 = LatLongMap::polar_angle(v1);
  const double c0 = std::cos(theta0), c1 = std::cos(theta1);
  const double dc = LatLongMap::band_height(theta0, theta1);  // c0 - c1, accurate
  // The integral of the shape over theta, times sin theta.
  double moment;
  if (form_ == Form::Quadratic) {
    moment = dc * (c0 * c0 + c0 * c1 + c1 * c1) / 3.0;  // (c0^3 - c1^3) / 3
  } else {
    // (max(c0,0)^2 - max(c1,0)^2) / 2
    const double p0 = std::max(c0, 0.0), p1 = std::max(c1, 0.0);
    const double dp = (c1 >= 0.0) ? dc : p0 - p1;
    moment = 0.5 * dp * (p0 + p1);
  }
  integral = (base_ * dc + gain_ * moment) * dphi;
  return true;
}

Vec3 GradientProbe::total_power() const {
  return base_ * kFourPi + gain_ * (form_ == Form::Quadratic ? kFourPi / 3.0 : kPi);
}

std::optional<Vec3> GradientProbe::upward_irradiance() const {
  return base_ * kPi + gain_ * (form_ == Form::Quadratic ? kPi / 2.0 : 2.0 * kPi / 3.0);
}

}  // namespace envkit::probes
