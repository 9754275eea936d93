#pragma once
/// @file latlong.h
/// Latitude-longitude (equirectangular) map, W x H (any size; 2:1 is usual).
///
/// Frame (the canonical envkit frame; OpenEXR's orientation): +Y up. With u = x / W in [0, 1] and
/// v = y / H in [0, 1] (row 0 at the top):
///   latitude  lat = pi (1/2 - v)           (+pi/2 at the top row edge: the +Y pole)
///   longitude lon = pi - 2 pi u            (u = 0 looks along -Z, u = 1/4 along +X, u = 1/2 along +Z,
///                                           u = 3/4 along -X)
///   dir = (sin lon cos lat, sin lat, cos lon cos lat).
/// TexelGrid::Centre: texel (i, j) centre at ((i + 0.5) / W, (j + 0.5) / H); texels tile the sphere exactly,
/// row j spans polar angle theta in [pi j / H, pi (j + 1) / H] and has the exact solid angle
/// (2 pi / W) (cos theta0 - cos theta1): never zero at the poles.
/// TexelGrid::Corner (OpenEXR's LATLONG): texel centres sit at u = i / (W - 1), v = j / (H - 1): the first and
/// last rows lie on the poles and the first and last columns duplicate (both look along -Z). Edge texels
/// cover half a texel of the domain, so solid angles still sum to 4 pi.
/// TexelGrid::CornerRows (Mitsuba 3's envmap emitter): columns as Centre, rows as Corner: texel (i, j) centre at
/// u = (i + 0.5) / W, v = j / (H - 1). The first and last rows sit on the poles and cover half a row each; no
/// column is duplicated.
#include <envkit/maps/parameterization.h>

#include <cmath>

namespace envkit {

class LatLongMap final : public Parameterization {
 public:
  LatLongMap(int width, int height, TexelGrid grid = TexelGrid::Centre);

  Kind kind() const override { return Kind::LatLong; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<LatLongMap>(*this); }
  bool same_grid(const Parameterization& other) const override;
  TexelGrid grid() const override { return grid_; }
  std::vector<std::vector<std::size_t>> twin_texels() const override;
  const LatLongMap* latlong_geometry() const override { return this; }

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  Vec2 to_image(const Vec3& dir) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2 pos) const override;
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

  /// The domain's axes as angles, the one place that says how (envkit canonical frame, +Y up): longitude
  /// lon = pi - 2 pi u (u = 0 and 1 at -Z, 1/2 at +Z, lon measured from +Z towards +X), latitude pi (1/2 - v), polar
  /// angle from +Y theta = pi v; and back. Fast paths that tabulate rows or columns build from these.
  static double longitude(double u) { return kPi - kTwoPi * u; }
  static double latitude(double v) { return kPi * (0.5 - v); }
  static double polar_angle(double v) { return kPi * v; }
  static double u_of_longitude(double lon) { return (kPi - lon) / kTwoPi; }
  static double v_of_polar_angle(double theta) { return theta / kPi; }
  /// Height along the polar axis of the band between the parallels at polar angles theta0 <= theta1 (radians):
  /// cos theta0 - cos theta1, as 2 sin((theta0 + theta1) / 2) sin((theta1 - theta0) / 2), which keeps full precision
  /// for nearby angles where the plain difference cancels. The band's solid angle is 2 pi times it (Archimedes), a
  /// texel of a W-column row 2 pi / W times it. The one place that writes this formula.
  static double band_height(double theta0, double theta1) {
    return 2.0 * std::sin(0.5 * (theta1 + theta0)) * std::sin(0.5 * (theta1 - theta0));
  }
  /// Radians per domain unit: along u at the equator (2 pi) and along v (pi).
  static constexpr double kRadiansPerU = kTwoPi;
  static constexpr double kRadiansPerV = kPi;

  /// Unit direction for (u, v) in the centre-grid domain: u = x / W, v = y / H.
  static Vec3 direction_from_uv(double u, double v);
  /// (u, v) in [0, 1) x [0, 1] of a direction (u = 0 at longitude pi, i.e. -Z).
  static Vec2 uv_from_direction(const Vec3& dir);
  /// The u of uv_from_direction alone, given horizontal = hypot(dir.x, dir.z) (callers that measure theta
  /// themselves skip the latitude).
  static double u_from_direction(const Vec3& dir, double horizontal);
  /// Sines and cosines of the texel centres' longitudes (one per column) and latitudes (one per row), for loops that
  /// visit every texel: the centre of texel (i, j) sees (sin_lon[i] cos_lat[j], sin_lat[j], cos_lon[i] cos_lat[j]),
  /// bit for bit to_direction at the centre.
  struct CentreAngles {
    std::vector<double> sin_lon, cos_lon, sin_lat, cos_lat;
  };
  CentreAngles centre_angles() const;
  /// Domain coordinates (u, v) of a continuous image position, per grid (u depends on x only, v on y only:
  /// to_direction(pos) == direction_from_uv(u, clamp(v, 0, 1))).
  Vec2 domain_from_image(Vec2 pos) const;

 private:
  Vec2 image_from_domain(Vec2 uv) const;
  bool corner_columns() const { return grid_ == TexelGrid::Corner; }
  bool corner_rows() const { return grid_ == TexelGrid::Corner || grid_ == TexelGrid::CornerRows; }
  TexelGrid grid_;
  double du_dx_, dv_dy_;  // domain units per pixel
  double max_x_, max_y_;  // largest positions inside the image
};

}  // namespace envkit
