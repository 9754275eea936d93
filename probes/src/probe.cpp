// Probe base class and the spherical geometry helpers shared by the probes.
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>

#include <cmath>

namespace envkit::probes {

Vec3 direction_from_elevation_azimuth(double elevation, double azimuth) {
  const double c = std::cos(elevation);
  return Vec3(std::sin(azimuth) * c, std::sin(elevation), std::cos(azimuth) * c);
}

double cap_solid_angle(double alpha) {
  // 2 pi (1 - cos a) = 4 pi sin^2(a / 2): no cancellation for the tiny suns this is used for.
  const double s = std::sin(0.5 * alpha);
  return kFourPi * s * s;
}

double latlong_rect_solid_angle(double u0, double u1, double v0, double v1) {
  if (!(u1 > u0) || !(v1 > v0)) return 0.0;
  return kTwoPi * (u1 - u0) * LatLongMap::band_height(LatLongMap::polar_angle(v0), LatLongMap::polar_angle(v1));
}

bool valid_radiance(const Vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && v.x >= 0 && v.y >= 0 && v.z >= 0;
}

Vec3 Probe::radiance(const Vec3& dir) const {
  Vec3 l = background(dir);
  for (std::size_t k = 0; k < features_.size(); ++k)
    if (in_feature(k, dir)) l += features_[k].excess;
  return l;
}

bool Probe::in_feature(std::size_t k, const Vec3& dir) const {
  // Chord test: |d - c| < 2 sin(bound / 2) keeps full precision for caps of a few arc seconds.
  const Feature& f = features_[k];
  const double chord = 2.0 * std::sin(0.5 * f.bound);
  return (dir - f.centre).length2() < chord * chord;
}

bool Probe::background_may_vary(const Vec3&, double) const { return false; }

bool Probe::integrate_latlong(double, double, double, double, Vec3&) const { return false; }

}  // namespace envkit::probes
