#pragma once
/// @file fisheye.h
/// Circular fisheye view: the image circle inscribed in the W x H image (centre
/// (W/2, H/2), radius min(W, H) / 2), the optical axis the view's forward
/// direction (view.h), image right and up its right and up.
///
/// A direction at angle theta from the axis lies at normalised radius r (1 on
/// the image circle, where theta is fov / 2 = h) given by the lens: equidistant
/// r = theta / h, equisolid r = sin(theta / 2) / sin(h / 2), orthographic r =
/// sin(theta) / sin(h), stereographic r = tan(theta / 2) / tan(h / 2). It is a
/// RadialMap, so solid angles of any sub-rectangle are exact (Green's theorem,
/// radial_map.h); texels outside the circle hold no data, directions beyond fov
/// / 2 map outside the image, and the view covers the sphere only for a
/// 360-degree equidistant or equisolid lens (whose rim is the single direction
/// behind the camera).
#include <envkit/maps/radial_map.h>
#include <envkit/maps/view.h>

namespace envkit {

class FisheyeMap final : public RadialMap {
 public:
  /// fov (view.fov_degrees) in (0, 360] ((0, 180] orthographic, (0, 360)
  /// stereographic). Throws Error.
  FisheyeMap(int width, int height, const ViewParams& view);

  Kind kind() const override { return Kind::Fisheye; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<FisheyeMap>(*this); }
  bool covers_sphere() const override;
  const ViewParams* view() const override { return &view_; }

  Vec2 to_image(const Vec3& dir) const override;
  double polar_angle(double r) const override;
  double radius_of_angle(double theta) const override;
  /// Exact solid angle inside the image circle: 2 pi (1 - cos(fov / 2)).
  double view_solid_angle() const { return kTwoPi * (1.0 - std::cos(half_)); }

 protected:
  double cap_density(double r) const override;
  double area_density(double r) const override;

 private:
  ViewParams view_;
  double half_;  // fov / 2, radians
  double k_;     // lens constant: h, sin(h/2), sin(h) or tan(h/2)
};

}  // namespace envkit
