#pragma once
/// @file vec.h
/// Vector and matrix types used throughout libenv (Imath, double precision for geometry).
///
/// World frame (the "canonical envkit frame"): right-handed, +Y up. Looking along +Z, +X is to the left
/// (as for a viewer standing inside the sphere with +Y up and -X on the right). Directions are unit vectors
/// pointing *from* the centre of the environment *towards* the light (the direction one looks in to see it).
#include <Imath/ImathMatrix.h>
#include <Imath/ImathVec.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace envkit {

using Vec2 = Imath::V2d;
using Vec3 = Imath::V3d;
/// 3x3 matrix acting on column vectors as `m * v` is NOT Imath's convention (Imath multiplies row vectors,
/// `v * m`). Use `apply(m, v)` to avoid mistakes: it computes the column-vector product M v.
using Mat3 = Imath::M33d;

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;
inline constexpr double kFourPi = 4.0 * std::numbers::pi;

/// Column-vector product M v with M[row][col].
inline Vec3 apply(const Mat3& m, const Vec3& v) {
  return Vec3(m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
              m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z);
}

/// Transpose (the inverse of a rotation).
inline Mat3 transposed(const Mat3& m) { return m.transposed(); }

/// Product A B in the column-vector sense: apply(A*B, v) == apply(A, apply(B, v)).
inline Mat3 compose(const Mat3& a, const Mat3& b) {
  Mat3 r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
  return r;
}

inline Mat3 identity3() { return Mat3(1, 0, 0, 0, 1, 0, 0, 0, 1); }
/// True when every entry of m is within `tolerance` of the identity's (exactly, by default).
inline bool is_identity(const Mat3& m, double tolerance = 0.0) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (!(std::abs(m[r][c] - (r == c ? 1.0 : 0.0)) <= tolerance)) return false;
  return true;
}

/// sqrt that never returns NaN for tiny negative round-off.
inline double safe_sqrt(double x) { return std::sqrt(std::max(0.0, x)); }
/// acos clamped to [-1, 1].
inline double safe_acos(double x) { return std::acos(std::clamp(x, -1.0, 1.0)); }
inline double safe_asin(double x) { return std::asin(std::clamp(x, -1.0, 1.0)); }

/// Angle between two unit vectors, accurate for tiny and near-pi angles (atan2 of |cross| and dot).
inline double angle_between(const Vec3& a, const Vec3& b) { return std::atan2((a % b).length(), a ^ b); }

}  // namespace envkit
