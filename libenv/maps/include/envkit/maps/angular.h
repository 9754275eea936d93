#pragma once
/// @file angular.h
/// Angular map (Debevec's light-probe format, as HDRShop writes it): the mirror ball unwarped so that the
/// angle from the centre direction grows linearly with the radius.
///
/// Frame: same as the mirror ball's (the ball photographed from +Z): the centre sees +Z, image right is +X,
/// image up is +Y. With normalized disk coordinates (u, v) (v up, unit radius), r = sqrt(u^2 + v^2), the angle from
/// +Z is pi r, i.e. for a direction D: r = acos(Dz) / (pi sqrt(Dx^2 + Dy^2)) and (u, v) = (Dx r, Dy r): Debevec's
/// formula, also what OIIO's maketx --lightprobe follows. (His angmap.cal puts -Z at the centre; envkit offers
/// that as the `angmap-cal` convention, a mirror of this frame.) d(omega)/dA = pi sin(pi r) / r, which goes to 0
/// at the rim; the rim is the single direction -Z.
#include <envkit/maps/radial_map.h>

namespace envkit {

class AngularMap final : public RadialMap {
 public:
  /// Disk inscribed in the image (square images are usual).
  AngularMap(int width, int height);

  Kind kind() const override { return Kind::AngularMap; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<AngularMap>(*this); }

  double polar_angle(double r) const override;
  double radius_of_angle(double theta) const override;

 protected:
  double cap_density(double r) const override;
  double area_density(double r) const override;
};

}  // namespace envkit
