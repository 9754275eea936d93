#pragma once
/// @file octahedral.h
/// Equal-area octahedral map (Clarberg 2008; pbrt-v4's EqualAreaSquareToSphere), square N x N.
///
/// Every texel has exactly the solid angle 4 pi / N^2, so importance needs no Jacobian and a square
/// power-of-two sum pyramid fits it exactly. Texel centres at ((i + 0.5) / N, (j + 0.5) / N).
/// Frame: the image centre sees +Y (up), the four corners see -Y; the mid-points of the right, bottom, left and
/// top edges see +Z, +X, -Z and -X (octahedron coordinates (x_o, y_o, z_o) = (Z, X, Y), a proper rotation).
/// Edges fold: a point just beyond an edge is the point mirrored across that edge's mid-point.
#include <envkit/maps/parameterization.h>

namespace envkit {

class OctahedralMap final : public Parameterization {
 public:
  explicit OctahedralMap(int size);

  Kind kind() const override { return Kind::Octahedral; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<OctahedralMap>(*this); }
  bool same_grid(const Parameterization& other) const override { return same_kind_and_size(other); }

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  Vec2 to_image(const Vec3& dir) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2) const override { return kFourPi / (double(width_) * height_); }
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

  /// Unit direction (map frame) seen at p in the unit square [0, 1]^2 (p = image position / N): the map without its
  /// size, for samplers that hold their own grid.
  static Vec3 direction_from_unit(Vec2 p);
  /// Inverse of direction_from_unit: the point of [0, 1]^2 that sees `dir` (any non-zero length).
  static Vec2 unit_from_direction(const Vec3& dir);
};

}  // namespace envkit
