#include <envkit/core/sh_basis.h>

#include <cmath>

namespace envkit {

namespace {

/// Any order: P_lm(z) / sin^m(theta) by the three-term recurrence in l (a polynomial in z, so no square root), times
/// sin^m(theta) (cos m phi, sin m phi) = (Re, Im) (x + i y)^m. The normalisation K_lm is carried in the recurrence's
/// start values so that no factorial overflows at high order.
void recurrence_basis(int order, const Vec3& d, double* out) {
  const double z = d.z;
  double re = 1.0, im = 0.0;                // (x + i y)^m
  double q = std::sqrt(1.0 / (4.0 * kPi));  // K_mm (2m - 1)!!, the start of column m
  for (int m = 0; m <= order; ++m) {
    if (m > 0) {
      const double r = re * d.x - im * d.y;
      im = re * d.y + im * d.x;
      re = r;
      q *= std::sqrt((2.0 * m + 1.0) / (2.0 * m));  // K_mm (2m - 1)!! / (K_(m-1)(m-1) (2m - 3)!!)
    }
    const double s = m == 0 ? 1.0 : std::sqrt(2.0);
    // Column m: N_l = K_lm P_lm / sin^m, starting at l = m (q) and l = m + 1.
    double prev = q;                                // l = m
    double cur = z * std::sqrt(2.0 * m + 3.0) * q;  // l = m + 1: P_(m+1)m = (2m + 1) z P_mm
    auto store = [&](int l, double n) {
      if (m == 0) {
        out[sh_index(l, 0)] = n;
      } else {
        out[sh_index(l, m)] = s * n * re;
        out[sh_index(l, -m)] = s * n * im;
      }
    };
    store(m, prev);
    if (m + 1 <= order) store(m + 1, cur);
    for (int l = m + 2; l <= order; ++l) {
      // Normalised recurrence: N_l = a_l (z N_(l-1) - b_l N_(l-2)), with
      // a_l = sqrt((4l^2 - 1) / (l^2 - m^2)), b_l = sqrt(((l-1)^2 - m^2) / (4 (l-1)^2 - 1)).
      const double l2 = double(l) * l, m2 = double(m) * m, lm1 = double(l - 1) * (l - 1);
      const double a = std::sqrt((4.0 * l2 - 1.0) / (l2 - m2));
      const double b = std::sqrt((lm1 - m2) / (4.0 * lm1 - 1.0));
      const double next = a * (z * cur - b * prev);
      prev = cur;
      cur = next;
      store(l, cur);
    }
  }
}

}  // namespace

void sh_basis(int order, const Vec3& d, double* out) {
  order = std::clamp(order, 0, kMaxShOrder);
  switch (order) {
    case 0:
      return sh_basis_closed_form<0>(d, out);
    case 1:
      return sh_basis_closed_form<1>(d, out);
    case 2:
      return sh_basis_closed_form<2>(d, out);
    case 3:
      return sh_basis_closed_form<3>(d, out);
    default:
      return recurrence_basis(order, d, out);
  }
}

void sh_rotate_zonal(int order, const double* zonal, const Vec3& axis, double* out) {
  order = std::clamp(order, 0, kMaxShOrder);
  sh_basis(order, axis, out);
  for (int l = 0; l <= order; ++l) {
    const double k = std::sqrt(4.0 * kPi / (2.0 * l + 1.0)) * zonal[l];
    for (int m = -l; m <= l; ++m) out[sh_index(l, m)] *= k;
  }
}

}  // namespace envkit
