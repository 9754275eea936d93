#pragma once
/// @file frame.h
/// Orthonormal shading frame built from a unit normal (Duff et al., "Building an Orthonormal Basis, Revisited",
/// JCGT 2017): branch-free apart from the sign of n.z, no singularity, accurate to round-off for every unit n.
///
/// Local coordinates: x = s (tangent), y = t (bitangent), z = n (the shading normal), right-handed (s x t = n).
/// BSDFs work in this frame: cos theta of a local direction is its z component.
#include <envkit/core/vec.h>

#include <cmath>

namespace envkit::render {

struct Frame {
  Vec3 s{1.0, 0.0, 0.0};  ///< tangent (local +x)
  Vec3 t{0.0, 1.0, 0.0};  ///< bitangent (local +y)
  Vec3 n{0.0, 0.0, 1.0};  ///< normal (local +z)

  Frame() = default;
  Frame(const Vec3& s_, const Vec3& t_, const Vec3& n_) : s(s_), t(t_), n(n_) {}

  /// Frame whose z axis is the unit normal n (Duff et al. 2017, listing 3). n must be unit length; a zero or
  /// non-finite n gives the identity frame (never NaN).
  static Frame from_normal(const Vec3& normal) {
    const double len2 = normal.length2();
    if (!(len2 > 0.0) || !std::isfinite(len2)) return Frame();
    const Vec3 nn = normal / std::sqrt(len2);
    const double sign = std::copysign(1.0, nn.z);
    const double a = -1.0 / (sign + nn.z);
    const double b = nn.x * nn.y * a;
    return Frame(Vec3(1.0 + sign * nn.x * nn.x * a, sign * b, -sign * nn.x), Vec3(b, sign + nn.y * nn.y * a, -nn.y),
                 nn);
  }

  /// World vector -> local coordinates (projections on s, t, n).
  Vec3 to_local(const Vec3& v) const { return Vec3(v ^ s, v ^ t, v ^ n); }
  /// Local coordinates -> world vector.
  Vec3 to_world(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

/// A surface point as a ray arriving along -wo_world sees it: both normals turned to wo's side, the shading frame of
/// the shading normal, and wo in that frame (wo.z <= 0 where the shading normal hides the side the ray came from).
struct SurfaceView {
  Vec3 ng;  ///< geometric normal on wo's side
  Frame frame;
  Vec3 wo;  ///< local frame
};
inline SurfaceView surface_view(Vec3 geometric_normal, Vec3 shading_normal, const Vec3& wo_world) {
  if ((geometric_normal ^ wo_world) < 0.0) {
    geometric_normal = -geometric_normal;
    shading_normal = -shading_normal;
  }
  const Frame frame = Frame::from_normal(shading_normal);
  return {geometric_normal, frame, frame.to_local(wo_world)};
}

}  // namespace envkit::render
