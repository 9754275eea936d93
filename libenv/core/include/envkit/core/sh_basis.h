#pragma once
/// @file sh_basis.h
/// The real spherical-harmonic basis of any order, evaluated at a direction: the one home of the basis in envkit
/// (SH projection, irradiance, SH product sampling and the Python module all evaluate it here).
///
/// Convention: real, orthonormal over the sphere (integral of Y_i Y_j d omega = delta_ij), WITHOUT the
/// Condon-Shortley phase, polar axis z, azimuth phi measured from +x towards +y, index i = l (l + 1) + m:
///   Y_l0  = K_l0 P_l0(z)
///   Y_lm  = sqrt(2) K_lm P_lm(z) cos(m phi)     (m > 0)
///   Y_l-m = sqrt(2) K_lm P_lm(z) sin(m phi)     (m > 0)
/// with K_lm = sqrt((2l + 1) / (4 pi) (l - m)! / (l + m)!) and P_lm the associated Legendre functions without the
/// (-1)^m phase. Band 1 is then sqrt(3 / (4 pi)) (y, z, x).
#include <envkit/core/vec.h>

namespace envkit {

/// The highest SH band (order) sh_basis evaluates: 289 coefficients.
inline constexpr int kMaxShOrder = 16;

/// Number of coefficients of SH up to band `order` (order 2: 9, order 3: 16).
inline constexpr int sh_count(int order) { return (order + 1) * (order + 1); }
/// Index of Y_lm in a coefficient vector.
inline constexpr int sh_index(int l, int m) { return l * (l + 1) + m; }

/// The closed-form basis up to band kOrder <= 3 at the unit direction d into out[sh_count(kOrder)]: products of the
/// direction's components. A template, for loops that want the band count as a constant (the values then stay in
/// registers); sh_basis calls it for these orders.
template <int kOrder>
[[gnu::always_inline]] inline void sh_basis_closed_form(const Vec3& d, double* out) {
  static_assert(kOrder >= 0 && kOrder <= 3);
  const double x = d.x, y = d.y, z = d.z;
  out[0] = 0.28209479177387814;  // 1 / (2 sqrt(pi))
  if constexpr (kOrder >= 1) {
    const double c1 = 0.4886025119029199;  // sqrt(3 / (4 pi))
    out[1] = c1 * y;
    out[2] = c1 * z;
    out[3] = c1 * x;
  }
  if constexpr (kOrder >= 2) {
    const double c2 = 1.0925484305920792;  // sqrt(15 / (4 pi))
    out[4] = c2 * x * y;
    out[5] = c2 * y * z;
    out[6] = 0.31539156525252005 * (3.0 * z * z - 1.0);  // sqrt(5 / (16 pi))
    out[7] = c2 * x * z;
    out[8] = 0.5462742152960396 * (x * x - y * y);  // sqrt(15 / (16 pi))
  }
  if constexpr (kOrder >= 3) {
    const double a = 0.5900435899266435;  // sqrt(35 / (32 pi))
    const double b = 2.890611442640554;   // sqrt(105 / (4 pi))
    const double c = 0.4570457994644658;  // sqrt(21 / (32 pi))
    const double e = 0.3731763325901154;  // sqrt(7 / (16 pi))
    const double f = 1.445305721320277;   // sqrt(105 / (16 pi))
    out[9] = a * y * (3.0 * x * x - y * y);
    out[10] = b * x * y * z;
    out[11] = c * y * (4.0 * z * z - x * x - y * y);
    out[12] = e * z * (2.0 * z * z - 3.0 * x * x - 3.0 * y * y);
    out[13] = c * x * (4.0 * z * z - x * x - y * y);
    out[14] = f * z * (x * x - y * y);
    out[15] = a * x * (x * x - 3.0 * y * y);
  }
}

/// Evaluates the basis up to `order` (clamped to 0 .. kMaxShOrder) at the unit direction d into
/// out[sh_count(order)]. Orders up to 3 use the closed-form polynomials; higher orders the Legendre recurrence in z
/// and the powers of (x + i y), so no trigonometric function is called.
void sh_basis(int order, const Vec3& d, double* out);

/// Coefficients, up to `order`, of the zonal function with band coefficients zonal[0 .. order] (around +z) turned to
/// the unit axis `axis`: c_lm = sqrt(4 pi / (2l + 1)) zonal[l] Y_lm(axis), into out[sh_count(order)].
void sh_rotate_zonal(int order, const double* zonal, const Vec3& axis, double* out);

}  // namespace envkit
