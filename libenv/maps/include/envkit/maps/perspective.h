#pragma once
/// @file perspective.h
/// Pinhole (rectilinear) view: a W x H image of the plane at unit distance
/// along the view direction.
///
/// With the view basis (view.h) forward F, right R, up U and t_x = tan(hfov /
/// 2), t_y = t_x H / W (square pixels), the continuous image position (x, y)
/// sees the direction of F + a R + b U with a = (2 x / W - 1) t_x and b = (1 -
/// 2 y / H) t_y. Exact solid angle of an image rectangle: the plane rectangle's
/// CubeMap::face_rect_solid_angle (atan2(a b, sqrt(a^2 + b^2 + 1)) at its
/// corners). Directions outside the frustum map outside the image: the view
/// does not cover the sphere (covers_sphere() is false), so embedding it into a
/// map gives coverage alpha, never black light.
///
/// Non-square pixels: with view.fov_v_degrees > 0, t_y = tan(vfov / 2) and
/// t_x = tan(fov / 2) independently.
///
/// Planar orthographic view (view.lens == Lens::Orthographic): the same image
/// rectangle on the plane, projected parallel to F onto the hemisphere around
/// F: (x, y) sees a R + b U + sqrt(1 - a^2 - b^2) F with t_x = sin(hfov / 2),
/// t_y = sin(vfov / 2) (vfov from square pixels unless given). Its corners must
/// stay on the hemisphere (t_x^2 + t_y^2 <= 1). The solid angle density is
/// 1 / sqrt(1 - a^2 - b^2), whose integral over [0, a] x [0, b] is
///   G(a, b) = a asin(b / sqrt(1 - a^2)) + b asin(a / sqrt(1 - b^2))
///             - atan(a b / sqrt(1 - a^2 - b^2)),
/// so texel solid angles are exact.
#include <envkit/maps/parameterization.h>
#include <envkit/maps/view.h>

namespace envkit {

class PerspectiveMap final : public Parameterization {
 public:
  /// fov (view.fov_degrees, across view.fov_axis) in (0, 180). Throws Error on
  /// bad arguments.
  PerspectiveMap(int width, int height, const ViewParams& view);

  Kind kind() const override { return Kind::Perspective; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<PerspectiveMap>(*this); }
  bool covers_sphere() const override { return false; }
  const ViewParams* view() const override { return &view_; }
  bool same_grid(const Parameterization& other) const override {
    return same_kind_and_size(other) && *other.view() == view_;
  }

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  /// Outside [0, W] x [0, H] (at (-1, -1) behind the camera) for directions the
  /// view does not see.
  Vec2 to_image(const Vec3& dir) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2 pos) const override;
  /// Taps beyond the image's edges see what the view does not: dropped.
  bool resolve_tap(int, int, int& i, int& j) const override { return i >= 0 && j >= 0 && i < width_ && j < height_; }

  /// Half-extents of the image plane at unit distance: tan(hfov / 2), tan(vfov
  /// / 2) (orthographic: sin(hfov / 2), sin(vfov / 2)).
  double tan_half_x() const { return tx_; }
  double tan_half_y() const { return ty_; }
  /// Exact solid angle of the whole view: 4 asin(sin(hfov / 2) sin(vfov / 2)) (orthographic: 4 G(t_x, t_y)).
  double view_solid_angle() const;
  bool orthographic() const { return orthographic_; }

 private:
  ViewParams view_;
  ViewBasis basis_;
  double tx_ = 1, ty_ = 1;
  bool orthographic_ = false;
};

}  // namespace envkit
