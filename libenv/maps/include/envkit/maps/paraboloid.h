#pragma once
/// @file paraboloid.h
/// Dual paraboloid map: two hemispheres side by side in a 2N x N image, each a disk inscribed in its N x N half.
///
/// A direction d in the hemisphere around axis A maps to (u, v) = (d . right, d . up) / (1 + d . A) on the unit
/// disk (Heidrich and Seidel), i.e. r = tan(theta / 2) with theta the angle from A; the rim is the equator.
/// Left half: A = +Z, image right -X, image up +Y. Right half: A = -Z, image right +X, image up +Y. Both halves are
/// views from inside the sphere, so the two images meet seamlessly along the middle (both see -X there).
/// d(omega)/dA = 4 / (1 + r^2)^2; each disk holds 2 pi. Texels outside the disks hold no data; filter taps
/// beyond a rim re-project into the other hemisphere.
#include <envkit/maps/radial_map.h>

namespace envkit {

class DualParaboloidMap final : public RadialMap {
 public:
  /// width must be 2 x height for the disks to be inscribed; other sizes use disks of radius min(W/2, H)/2.
  DualParaboloidMap(int width, int height);

  Kind kind() const override { return Kind::DualParaboloid; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<DualParaboloidMap>(*this); }
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

  double polar_angle(double r) const override;
  double radius_of_angle(double theta) const override;

 protected:
  double cap_density(double r) const override;
  double area_density(double r) const override { return 4.0 / ((1.0 + r * r) * (1.0 + r * r)); }
};

}  // namespace envkit
