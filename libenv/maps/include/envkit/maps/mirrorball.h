#pragma once
/// @file mirrorball.h
/// Mirror ball: an orthographic photograph of a perfectly reflective sphere.
///
/// Frame: the camera sits on +Z looking along -Z with +Y up, so the image's right is +X. A point of the ball at
/// normalized disk coordinates (x, y) (y up, unit radius) has normal n = (x, y, sqrt(1 - x^2 - y^2)) and reflects
/// the direction 2 n_z n - (0, 0, 1): the centre sees +Z (back towards the camera), and the angle theta from +Z
/// satisfies r = sin(theta / 2). The whole rim is the single direction -Z (straight behind the ball):
/// to_image(-Z) returns the rim point to the right of the centre. d(omega)/dA = 4 on the unit disk, so the
/// ball holds 4 pi; texels outside the ball hold no data (solid angle 0, alpha/coverage 0 when resampled).
/// For photographs, the ball's centre and radius are given in pixels (default: the inscribed circle).
#include <envkit/maps/radial_map.h>

namespace envkit {

class MirrorBallMap final : public RadialMap {
 public:
  /// Ball inscribed in the image: centre (W/2, H/2), radius min(W, H)/2.
  MirrorBallMap(int width, int height);
  /// Ball at (cx, cy) with radius `radius`, all in pixels (continuous coordinates: the top-left corner is 0, 0).
  MirrorBallMap(int width, int height, double cx, double cy, double radius);

  Kind kind() const override { return Kind::MirrorBall; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<MirrorBallMap>(*this); }

  double polar_angle(double r) const override;
  double radius_of_angle(double theta) const override;

 protected:
  double cap_density(double r) const override;
  double area_density(double) const override { return 4.0; }
};

}  // namespace envkit
