// Checkerboard of (theta, u) cells on the sphere.
#include <envkit/core/error.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace envkit::probes {

CheckerProbe::CheckerProbe(int n_theta, int n_phi, Vec3 colour_a, Vec3 colour_b)
    : n_theta_(n_theta), n_phi_(n_phi), colour_a_(colour_a), colour_b_(colour_b) {
  if (n_theta < 1 || n_phi < 1 || n_theta > 1 << 20 || n_phi > 1 << 20)
    throw Error("checker probe: cell counts must be in [1, 2^20]");
  if (!valid_radiance(colour_a) || !valid_radiance(colour_b))
    throw Error("checker probe: colours must be finite and >= 0");
}

std::string CheckerProbe::describe() const {
  std::ostringstream s;
  s << "checker: " << n_theta_ << " x " << n_phi_ << " cells of (" << colour_a_.x << ", " << colour_a_.y << ", "
    << colour_a_.z << ") and (" << colour_b_.x << ", " << colour_b_.y << ", " << colour_b_.z << ")";
  return s.str();
}

Vec3 CheckerProbe::background(const Vec3& dir) const {
  const Vec2 uv = LatLongMap::uv_from_direction(dir);  // v = theta / pi exactly as the lat-long map has it
  const int a = std::clamp(static_cast<int>(std::floor(uv.y * n_theta_)), 0, n_theta_ - 1);
  const int b = std::clamp(static_cast<int>(std::floor(uv.x * n_phi_)), 0, n_phi_ - 1);
  return colour(a, b);
}

bool CheckerProbe::background_may_vary(const Vec3& dir, double radius) const {
  if (colour_a_ == colour_b_ || (n_theta_ == 1 && n_phi_ == 1)) return false;
  if (radius >= 0.5 * kPi) return true;
  const Vec2 uv = LatLongMap::uv_from_direction(dir);
  const double theta = LatLongMap::polar_angle(uv.y);
  // Parallels theta = k pi / n_theta, k = 1 .. n_theta - 1.
  const double k = std::round(uv.y * n_theta_);
  if (k >= 1 && k <= n_theta_ - 1 && std::abs(theta - LatLongMap::polar_angle(k / n_theta_)) < radius) return true;
  if (n_phi_ == 1) return false;
  // Meridians meet at the poles; away from them the cap spans azimuths within asin(sin r / sin theta).
  const double sin_theta = std::sin(theta);
  if (theta < radius || kPi - theta < radius || std::sin(radius) >= sin_theta) return true;
  const double half_width = std::asin(std::sin(radius) / sin_theta);
  const double m = std::round(uv.x * n_phi_);  // nearest meridian, m = n_phi is the seam again
  return std::abs(uv.x - m / n_phi_) * kTwoPi < half_width;
}

double CheckerProbe::discontinuity_length() const {
  if (colour_a_ == colour_b_) return 0.0;
  // Parallel k of n_theta - 1 has length 2 pi sin(k pi / n_theta); their sines sum to cot(pi / (2 n_theta)).
  const double parallels = n_theta_ > 1 ? kTwoPi / std::tan(kPi / (2.0 * n_theta_)) : 0.0;
  // With an odd n_phi (one cell too) the seam joins cells of one colour.
  const int meridians = n_phi_ - (n_phi_ & 1);
  return parallels + kPi * meridians;
}

bool CheckerProbe::integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const {
  integral = Vec3(0.0);
  u0 = std::clamp(u0, 0.0, 1.0), u1 = std::clamp(u1, 0.0, 1.0);
  v0 = std::clamp(v0, 0.0, 1.0), v1 = std::clamp(v1, 0.0, 1.0);
  if (!(u1 > u0) || !(v1 > v0)) return true;
  const int a0 = std::clamp(static_cast<int>(std::floor(v0 * n_theta_)), 0, n_theta_ - 1);
  const int a1 = std::clamp(static_cast<int>(std::ceil(v1 * n_theta_)) - 1, a0, n_theta_ - 1);
  const int b0 = std::clamp(static_cast<int>(std::floor(u0 * n_phi_)), 0, n_phi_ - 1);
  const int b1 = std::clamp(static_cast<int>(std::ceil(u1 * n_phi_)) - 1, b0, n_phi_ - 1);
  for (int a = a0; a <= a1; ++a) {
    const double va = std::max(v0, static_cast<double>(a) / n_theta_);
    const double vb = std::min(v1, static_cast<double>(a + 1) / n_theta_);
    if (!(vb > va)) continue;
    for (int b = b0; b <= b1; ++b) {
      const double ua = std::max(u0, static_cast<double>(b) / n_phi_);
      const double ub = std::min(u1, static_cast<double>(b + 1) / n_phi_);
      if (ub > ua) integral += colour(a, b) * latlong_rect_solid_angle(ua, ub, va, vb);
    }
  }
  return true;
}

Vec3 CheckerProbe::total_power() const {
  // Band a holds ceil(n_phi / 2) cells of the colour it starts with and floor(n_phi / 2) of the other.
  Vec3 power(0.0);
  const double cell_phi = kTwoPi / n_phi_;
  const int first = (n_phi_ + 1) / 2, second = n_phi_ / 2;
  for (int a = 0; a < n_theta_; ++a) {
    const double band =
        cell_phi * LatLongMap::band_height(LatLongMap::polar_angle(static_cast<double>(a) / n_theta_),
                                           LatLongMap::polar_angle(static_cast<double>(a + 1) / n_theta_));
    power += (colour(a, 0) * first + colour(a, 1) * second) * band;
  }
  return power;
}

std::optional<Vec3> CheckerProbe::upward_irradiance() const {
  // Over a band [theta0, theta1] of the upper hemisphere, integral of cos theta d omega per unit azimuth is
  // (sin^2 theta1 - sin^2 theta0) / 2.
  Vec3 e(0.0);
  const double cell_phi = kTwoPi / n_phi_;
  const int first = (n_phi_ + 1) / 2, second = n_phi_ / 2;
  for (int a = 0; a < n_theta_; ++a) {
    const double t0 = LatLongMap::polar_angle(static_cast<double>(a) / n_theta_);
    const double t1 = std::min(LatLongMap::polar_angle(static_cast<double>(a + 1) / n_theta_), 0.5 * kPi);
    if (!(t1 > t0)) break;
    const double s0 = std::sin(t0), s1 = std::sin(t1);
    e += (colour(a, 0) * first + colour(a, 1) * second) * (cell_phi * 0.5 * (s1 * s1 - s0 * s0));
  }
  return e;
}

}  // namespace envkit::probes
