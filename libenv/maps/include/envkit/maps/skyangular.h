#pragma once
/// @file skyangular.h
/// Sky angular map: the upper hemisphere (+Y up) in the angular (equidistant) projection, skylibs' `skyangular`.
///
/// A disk inscribed in the image (square images are usual; centre (W/2, H/2), radius min(W, H) / 2). With
/// normalized disk coordinates (x, y) (x right, y up, 1 on the rim) and r = sqrt(x^2 + y^2), the zenith angle is
/// (pi / 2) r: the centre sees the zenith +Y, the rim the horizon. Image right is -X and image up is -Z:
///   dir = cos(pi r / 2) (+Y) + sin(pi r / 2) (x (-X) + y (-Z)) / r.
/// Seen from below, it is the sky as a camera looking straight up shows it (an equidistant fisheye of 180
/// degrees). d(omega)/dA = (pi / 2) sin(pi r / 2) / r on the unit disk; it is a RadialMap, so the solid angle of any
/// sub-rectangle is exact (Green's theorem, radial_map.h) and the texels sum to 2 pi.
///
/// skylibs (envmap/projections.py, skyangular2world) puts its +X on the right and its +Z at the top; its world is
/// envkit's turned half a turn about +Y (skylibs x, z = envkit -x, -z), as for its `latlong` and `skylatlong`
/// (skylatlong.h), so the images of the two libraries are the same pixels: skylibs' latlong -> skyangular and
/// envkit's agree, and skyangular and skylatlong agree with each other in both.
///
/// The map does not cover the sphere: directions below the horizon map outside the image (to_image returns
/// (-1, -1)), texels outside the disk hold no data, and maps made from it carry coverage alpha.
#include <envkit/maps/radial_map.h>

namespace envkit {

class SkyAngularMap final : public RadialMap {
 public:
  SkyAngularMap(int width, int height);

  Kind kind() const override { return Kind::SkyAngular; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<SkyAngularMap>(*this); }
  bool covers_sphere() const override { return false; }

  /// Directions below the horizon (y < 0) give (-1, -1), outside the image.
  Vec2 to_image(const Vec3& dir) const override;
  double polar_angle(double r) const override;
  double radius_of_angle(double theta) const override;

 protected:
  double cap_density(double r) const override;
  double area_density(double r) const override;
};

}  // namespace envkit
