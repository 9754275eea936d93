#pragma once
/// @file skylatlong.h
/// Sky lat-long: the upper hemisphere (+Y up) as a W x H lat-long, 4:1 usual (skylibs' `skylatlong`).
///
/// It is the upper half of the centre-sampled W x 2H lat-long of latlong.h, texel for texel: with u = x / W and
/// v = y / H (row 0 at the top),
///   polar angle from +Y (zenith angle)  theta = (pi / 2) v   (0 on the top edge, pi/2 = the horizon on the bottom
///                                                            edge: elevation 90 degrees down to 0 over the height)
///   longitude                           lon = pi - 2 pi u    (as latlong.h: u = 0 looks along -Z, 1/4 along +X,
///                                                            1/2 along +Z, 3/4 along -X)
///   dir = (sin lon sin theta, cos theta, cos lon sin theta).
/// Texel (i, j) is texel (i, j) of that lat-long, so its exact solid angle is the lat-long's band formula,
/// (2 pi / W) (cos theta0 - cos theta1) over its row's polar angles; the texels sum to 2 pi.
///
/// skylibs (envmap/projections.py, skylatlong2world) maps the same image with phi = pi v / 2 from its +Y and
/// azimuth pi (2u - 1), u = 1/2 looking along its -Z: the same pixels as envkit's lat-long top half, in skylibs'
/// world, which is envkit's turned half a turn about +Y (skylibs x, z = envkit -x, -z), exactly as skylibs'
/// `latlong` relates to envkit's `latlong`. So skylibs' latlong -> skylatlong and envkit's give the same image.
///
/// The map does not cover the sphere: directions below the horizon map outside the image (to_image returns
/// (-1, -1)), and maps made from it carry coverage alpha, 0 below the horizon.
#include <envkit/maps/latlong.h>
#include <envkit/maps/parameterization.h>

namespace envkit {

class SkyLatLongMap final : public Parameterization {
 public:
  SkyLatLongMap(int width, int height);

  Kind kind() const override { return Kind::SkyLatLong; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<SkyLatLongMap>(*this); }
  bool same_grid(const Parameterization& other) const override { return same_kind_and_size(other); }
  bool covers_sphere() const override { return false; }
  /// The W x 2H lat-long whose upper half this map is.
  const LatLongMap* latlong_geometry() const override { return &sphere_; }

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  /// Directions below the horizon (y < 0) give (-1, -1), outside the image.
  Vec2 to_image(const Vec3& dir) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2 pos) const override;
  /// Longitude wraps, the zenith row clamps; taps below the horizon hold no data.
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

 private:
  LatLongMap sphere_;  // W x 2H, centre-sampled
  double max_y_;       // the largest position inside the image
};

}  // namespace envkit
