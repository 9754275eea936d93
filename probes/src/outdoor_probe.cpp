// The built-in default probe: a procedural outdoor sky with sun, clouds, ground, silhouettes and markers.
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/sampling/sampler.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <sstream>
#include <utility>
#include <vector>

namespace envkit::probes {

namespace {

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

Vec3 mix(const Vec3& a, const Vec3& b, double t) { return a + (b - a) * t; }

// Angle wrapped into (-pi, pi].
double wrap(double a) {
  a = std::remainder(a, kTwoPi);
  return a <= -kPi ? a + kTwoPi : a;
}

// Integer lattice hash (the lowbias32 finaliser of envkit's sampler): platform independent, so the probe is the
// same everywhere.
std::uint32_t hash(std::int32_t x, std::int32_t y, std::uint32_t seed) {
  return hash_u32(seed * 0x9E3779B9u ^ static_cast<std::uint32_t>(x) * 0x85EBCA6Bu ^
                  static_cast<std::uint32_t>(y) * 0xC2B2AE35u);
}

double hash01(std::int32_t x, std::int32_t y, std::uint32_t seed) { return hash(x, y, seed) * (1.0 / 4294967296.0); }

// Value noise in [0, 1] with quintic interpolation (C2, so the clouds have no creases).
double value_noise(double x, double y, std::uint32_t seed) {
  x = std::clamp(x, -1e6, 1e6), y = std::clamp(y, -1e6, 1e6);
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int32_t>(fx), iy = static_cast<std::int32_t>(fy);
  const double tx = x - fx, ty = y - fy;
  const double sx = tx * tx * tx * (tx * (tx * 6.0 - 15.0) + 10.0);
  const double sy = ty * ty * ty * (ty * (ty * 6.0 - 15.0) + 10.0);
  const double a = hash01(ix, iy, seed), b = hash01(ix + 1, iy, seed);
  const double c = hash01(ix, iy + 1, seed), d = hash01(ix + 1, iy + 1, seed);
  return (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy;
}

// Five octaves, each rotated so the lattice does not show; result roughly in [0, 1], mean 0.5.
double fbm(double x, double y, std::uint32_t seed) {
  double sum = 0.0, amplitude = 0.5, norm = 0.0;
  for (int octave = 0; octave < 5; ++octave) {
    sum += amplitude * value_noise(x, y, seed + static_cast<std::uint32_t>(octave) * 1013u);
    norm += amplitude;
    const double rx = 1.6 * x - 1.2 * y + 3.1, ry = 1.2 * x + 1.6 * y - 1.7;  // x2 with a 37 deg turn
    x = rx, y = ry;
    amplitude *= 0.5;
  }
  return sum / norm;
}

// Palette (linear, "W/sr"): sky about 0.3 - 1.6, ground about 0.1 - 0.2.
const Vec3 kZenith(0.16, 0.32, 0.85);
const Vec3 kHorizon(1.30, 1.42, 1.60);
const Vec3 kGlow(1.0, 0.78, 0.50);
const Vec3 kCloudLit(1.85, 1.85, 1.90);
const Vec3 kCloudShade(0.62, 0.66, 0.76);
const Vec3 kGroundDark(0.080, 0.060, 0.040);
const Vec3 kGroundLight(0.180, 0.130, 0.085);
const Vec3 kGroundHaze(0.50, 0.54, 0.62);
const Vec3 kMountain(0.045, 0.052, 0.070);
const Vec3 kBuilding(0.028, 0.028, 0.032);

constexpr double kTile = 2.0;  // ground tile size, in viewer heights

// Orientation markers near the horizon.
constexpr double kMarkerElevation = radians(3.0);
constexpr double kMarkerRadius = radians(2.0);
struct Marker {
  double azimuth;
  Vec3 colour;
};
const Marker kMarkers[3] = {{radians(90.0), Vec3(6.0, 0.25, 0.2)},   // +X red
                            {radians(0.0), Vec3(0.25, 5.0, 0.3)},    // +Z green
                            {radians(-90.0), Vec3(0.3, 0.6, 9.0)}};  // -X blue
const Vec3 kMarkerDirections[3] = {direction_from_elevation_azimuth(kMarkerElevation, kMarkers[0].azimuth),
                                   direction_from_elevation_azimuth(kMarkerElevation, kMarkers[1].azimuth),
                                   direction_from_elevation_azimuth(kMarkerElevation, kMarkers[2].azimuth)};
const double kMarkerChord2 = 4.0 * std::sin(0.5 * kMarkerRadius) * std::sin(0.5 * kMarkerRadius);

// Silhouettes: [azimuth0, azimuth1] and the maximum height of each, radians.
constexpr double kMountainAz0 = radians(-80.0), kMountainAz1 = radians(-10.0), kMountainMax = radians(10.0);
constexpr double kCityAz0 = radians(110.0), kCityAz1 = radians(170.0), kCityMax = radians(6.0);
constexpr int kCityBlocks = 15;

// Ridge profile: a sine window times a sum of sines (never above 1, never below 0.12).
double mountain_height(double azimuth) {
  if (azimuth <= kMountainAz0 || azimuth >= kMountainAz1) return 0.0;
  const double t = (azimuth - kMountainAz0) / (kMountainAz1 - kMountainAz0);
  const double ridge = 0.55 + 0.22 * std::sin(9.3 * t + 1.1) + 0.13 * std::sin(23.0 * t + 0.4) +
                       0.05 * std::sin(61.0 * t + 2.0) + 0.03 * std::sin(143.0 * t);
  return kMountainMax * std::sin(kPi * t) * ridge;
}
// Lipschitz bound of mountain_height (rad per rad of azimuth): |d/dt (sin(pi t) ridge)| <= pi * 1 + 1 * sum of
// amplitude x frequency, divided by the range's width.
const double kMountainSlope =
    kMountainMax * (kPi + 0.22 * 9.3 + 0.13 * 23.0 + 0.05 * 61.0 + 0.03 * 143.0) / (kMountainAz1 - kMountainAz0);

// The skyline: kCityBlocks blocks over the azimuth range; block b holds a gap then a building, some with a
// narrower upper part. Heights are piecewise constant in azimuth.
double city_t(double azimuth) { return (azimuth - kCityAz0) / (kCityAz1 - kCityAz0) * kCityBlocks; }
double city_gap(int block, std::uint32_t seed) { return 0.08 + 0.2 * hash01(block, 23, seed); }
constexpr double kTowerSteps[2] = {0.45, 0.8};

double city_height(double azimuth, std::uint32_t seed) {
  if (azimuth <= kCityAz0 || azimuth >= kCityAz1) return 0.0;
  const double t = city_t(azimuth);
  const int block = std::clamp(static_cast<int>(t), 0, kCityBlocks - 1);
  const double within = t - block;
  if (hash01(block, 17, seed) < 0.15) return 0.0;  // an empty lot
  if (within < city_gap(block, seed)) return 0.0;
  const double h = radians(1.2) + (kCityMax - radians(1.2)) * hash01(block, 29, seed);
  if (hash01(block, 31, seed) < 0.35 && (within < kTowerSteps[0] || within > kTowerSteps[1])) return 0.7 * h;
  return h;
}

// Whether the skyline's outline may cross the cap: a vertical edge inside its azimuth span (while the cap
// reaches below the tallest building), or the roof line at the cap's azimuth within the cap's radius.
bool city_may_vary(double elevation, double azimuth, double radius, double half_width, std::uint32_t seed) {
  if (elevation - radius >= kCityMax) return false;
  const double t0 = city_t(azimuth - half_width), t1 = city_t(azimuth + half_width);
  if (t1 <= 0.0 || t0 >= kCityBlocks) return false;
  if (std::floor(t0) != std::floor(t1)) return true;  // a block boundary (or the range's end)
  const double b = std::floor(t0);
  const double steps[3] = {b + city_gap(static_cast<int>(b), seed), b + kTowerSteps[0], b + kTowerSteps[1]};
  for (double s : steps)
    if (s > t0 && s < t1) return true;
  return std::abs(elevation - city_height(azimuth, seed)) < radius;
}

}  // namespace

OutdoorProbe::OutdoorProbe(OutdoorSettings settings) : settings_(settings) {
  Feature sun;
  sun.centre = direction_from_elevation_azimuth(radians(settings.sun_elevation_deg), radians(settings.sun_azimuth_deg));
  sun.bound = radians(settings.sun_radius_deg);
  sun.is_disk = true;
  sun.solid_angle = cap_solid_angle(sun.bound);
  sun.excess = settings.sun_radiance;
  sun.leaf_radius = sun.bound / 16.0;
  features_.push_back(sun);
}

std::string OutdoorProbe::describe() const {
  std::ostringstream s;
  s << "default outdoor sky: sun radius " << settings_.sun_radius_deg << " deg at elevation "
    << settings_.sun_elevation_deg << " deg, azimuth " << settings_.sun_azimuth_deg << " deg; clouds (seed "
    << settings_.seed << "), ground tiles, mountains at azimuth -80..-10 deg, city at 110..170 deg, markers "
    << "+X red, +Z green, -X blue";
  return s.str();
}

Vec3 OutdoorProbe::sky(const Vec3& dir) const {
  const double y = std::max(dir.y, 0.0);
  Vec3 l = mix(kHorizon, kZenith, std::pow(y, 0.45));
  // Glow around the sun: a tight aureole and a broad one.
  const Vec3& sun = sun_direction();
  const double a = 2.0 * std::asin(std::min(1.0, 0.5 * (dir - sun).length()));
  l += kGlow * (2.0 * std::exp(-a / 0.05) + 0.35 * std::exp(-a / 0.4));

  // Clouds on a layer above the viewer: (x, z) / height gives perspective (small and dense towards the horizon,
  // where they fade out before they would alias).
  const double fade = smoothstep(0.02, 0.25, y);
  if (fade > 0.0 && settings_.cloud_cover > 0.0) {
    const double scale = 1.3 / (y + 0.15);
    const double qx = dir.x * scale + 11.3, qz = dir.z * scale - 4.7;
    const double lo = 0.78 - 0.40 * std::clamp(settings_.cloud_cover, 0.0, 1.0);
    const double n = fbm(qx, qz, settings_.seed);
    const double density = smoothstep(lo, lo + 0.16, n) * fade;
    if (density > 0.0) {
      // Self-shadowing: denser cloud towards the sun means a darker underside.
      const double ahead = fbm(qx + 0.15 * sun.x, qz + 0.15 * sun.z, settings_.seed);
      const double shade = smoothstep(-0.05, 0.12, ahead - n);
      Vec3 cloud = mix(kCloudLit, kCloudShade, shade);
      cloud += kGlow * (1.5 * std::exp(-a / 0.15));  // silver lining near the sun
      l = mix(l, cloud, 0.93 * density);
    }
  }
  return l;
}

Vec3 OutdoorProbe::ground(const Vec3& dir) const {
  const double depth = -dir.y;  // > 0 below the horizon
  if (!(depth > 1e-9)) return kGroundHaze;
  // Viewer 1 unit above a ground plane tiled with 2-unit squares aligned with X and Z.
  const double px = dir.x / depth, pz = dir.z / depth;
  const double distance = std::hypot(px, pz);
  const double s = std::sin(kPi * px / kTile) * std::sin(kPi * pz / kTile);
  const double tile = smoothstep(-0.08, 0.08, s);
  const double contrast = std::exp(-distance / 40.0);  // fade the pattern before it aliases
  Vec3 g = mix(kGroundDark, kGroundLight, 0.5 + (tile - 0.5) * contrast);
  // Soft darkening towards the nadir (viewer's own shadow side) and haze at the horizon.
  g *= 0.75 + 0.25 * smoothstep(0.0, 0.6, 1.0 - depth);
  return mix(g, kGroundHaze, 0.75 * std::exp(-depth / 0.04));
}

Vec3 OutdoorProbe::background(const Vec3& dir) const {
  const double elevation = std::atan2(dir.y, std::hypot(dir.x, dir.z));
  if (elevation < 0.0) return ground(dir);
  const double azimuth = std::atan2(dir.x, dir.z);
  for (int m = 0; m < 3; ++m)
    if ((dir - kMarkerDirections[m]).length2() < kMarkerChord2) return kMarkers[m].colour;
  if (elevation < mountain_height(azimuth)) {
    // Aerial perspective: the foot of the range is lighter.
    return mix(kMountain, kHorizon * 0.6, 0.45 * std::exp(-elevation / radians(1.5)));
  }
  if (elevation < city_height(azimuth, settings_.seed)) return kBuilding;
  return sky(dir);
}

bool OutdoorProbe::background_may_vary(const Vec3& dir, double radius) const {
  const double elevation = std::atan2(dir.y, std::hypot(dir.x, dir.z));
  if (std::abs(elevation) < radius) return true;  // the horizon
  if (elevation < 0.0) return false;
  for (const Vec3& m : kMarkerDirections)
    if (angle_between(dir, m) < kMarkerRadius + radius) return true;
  // Silhouettes: the cap's elevation band must reach them; then test their outlines over its azimuth span.
  if (elevation - radius >= std::max(kMountainMax, kCityMax)) return false;
  if (radius >= 0.5 * kPi - elevation) return true;  // the cap reaches the zenith
  const double half_width = std::asin(std::min(1.0, std::sin(radius) / std::cos(elevation)));
  if (half_width >= 0.5 * kPi) return true;
  const double azimuth = std::atan2(dir.x, dir.z);
  // Mountains: within the span the ridge stays within slope x half_width of its value at the centre.
  const double mountain_mid = 0.5 * (kMountainAz0 + kMountainAz1);
  const double mountain_half = 0.5 * (kMountainAz1 - kMountainAz0);
  if (std::abs(wrap(azimuth - mountain_mid)) < mountain_half + half_width &&
      std::abs(elevation - mountain_height(azimuth)) < radius + kMountainSlope * half_width)
    return true;
  // The skyline, in an unwrapped azimuth near its range (it does not cross the +-180 deg seam).
  const double city_mid = 0.5 * (kCityAz0 + kCityAz1);
  return city_may_vary(elevation, city_mid + wrap(azimuth - city_mid), radius, half_width, settings_.seed);
}

namespace {

bool same_settings(const OutdoorSettings& a, const OutdoorSettings& b) {
  return a.sun_elevation_deg == b.sun_elevation_deg && a.sun_azimuth_deg == b.sun_azimuth_deg &&
         a.sun_radius_deg == b.sun_radius_deg && a.sun_radiance == b.sun_radiance && a.seed == b.seed &&
         a.cloud_cover == b.cloud_cover;
}

/// The power of a probe with these settings: probes with equal settings have equal power, and a process that
/// builds many of them (a Python session, a batch, the fuzzers) rasterizes once per settings instead of once per
/// probe. The few most recent settings are kept.
Vec3 power_for(const OutdoorSettings& settings, const OutdoorProbe& probe) {
  static std::mutex mutex;
  static std::vector<std::pair<OutdoorSettings, Vec3>> recent;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [s, power] : recent)
      if (same_settings(s, settings)) return power;
  }
  const LatLongMap map(512, 256);
  const Vec3 power = image_power(rasterize(probe, map), map);
  const std::lock_guard<std::mutex> lock(mutex);
  if (recent.size() >= 16) recent.erase(recent.begin());
  recent.emplace_back(settings, power);
  return power;
}

}  // namespace

Vec3 OutdoorProbe::total_power() const {
  std::call_once(power_once_, [this] { power_ = power_for(settings_, *this); });
  return power_;
}

std::unique_ptr<Probe> make_default_probe() { return std::make_unique<OutdoorProbe>(); }

}  // namespace envkit::probes
