// The SH basis of any order against independent facts: the addition theorem (Legendre polynomials from <cmath>),
// orthonormality by a quadrature exact for the products, a literature closed form with its sign, the closed-form
// low bands against the recurrence, and the zonal rotation.
#include <envkit/core/gauss_legendre.h>
#include <envkit/core/sh_basis.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

using namespace envkit;

namespace {

Vec3 random_direction(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double z = 2.0 * u(rng) - 1.0, phi = 2.0 * kPi * u(rng), r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vec3(r * std::cos(phi), r * std::sin(phi), z);
}

TEST(ShBasis, AdditionTheoremAtEveryBand) {
  // sum_m Y_lm(a) Y_lm(b) = (2l + 1) / (4 pi) P_l(a . b): every band, every sign convention mistake shows.
  std::mt19937 rng(7);
  std::vector<double> ya(sh_count(kMaxShOrder)), yb(sh_count(kMaxShOrder));
  for (int trial = 0; trial < 50; ++trial) {
    const Vec3 a = random_direction(rng), b = random_direction(rng);
    sh_basis(kMaxShOrder, a, ya.data());
    sh_basis(kMaxShOrder, b, yb.data());
    for (int l = 0; l <= kMaxShOrder; ++l) {
      double sum = 0.0;
      for (int m = -l; m <= l; ++m) sum += ya[sh_index(l, m)] * yb[sh_index(l, m)];
      EXPECT_NEAR(sum, (2.0 * l + 1.0) / (4.0 * kPi) * std::legendre(l, a ^ b), 1e-12 * (2 * l + 1)) << l;
    }
  }
}

TEST(ShBasis, OrthonormalUpToTheHighestOrder) {
  // Gauss-Legendre in z times equally spaced phi: exact for the products of two functions of band <= 16.
  const int order = kMaxShOrder, count = sh_count(order), nz = order + 2, nphi = 2 * order + 3;
  std::vector<double> gram(std::size_t(count) * count, 0.0), y(count);
  detail::for_nodes(-1.0, 1.0, nz, [&](double z, double wz) {
    for (int k = 0; k < nphi; ++k) {
      const double phi = 2.0 * kPi * (k + 0.5) / nphi, r = std::sqrt(1.0 - z * z);
      sh_basis(order, Vec3(r * std::cos(phi), r * std::sin(phi), z), y.data());
      const double w = wz * 2.0 * kPi / nphi;
      for (int i = 0; i < count; ++i)
        for (int j = 0; j < count; ++j) gram[std::size_t(i) * count + j] += w * y[i] * y[j];
    }
  });
  for (int i = 0; i < count; ++i)
    for (int j = 0; j < count; ++j)
      ASSERT_NEAR(gram[std::size_t(i) * count + j], i == j ? 1.0 : 0.0, 1e-11) << i << " " << j;
}

TEST(ShBasis, MatchesTheTabulatedBandFour) {
  // Y_40 = 3 / (16 sqrt(pi)) (35 z^4 - 30 z^2 + 3); Y_44 = (3 / 16) sqrt(35 / pi) (x^4 - 6 x^2 y^2 + y^4);
  // Y_4-4 = (3 / 4) sqrt(35 / pi) x y (x^2 - y^2). Positive at +x: no Condon-Shortley phase.
  std::mt19937 rng(3);
  double y[sh_count(4)];
  for (int trial = 0; trial < 20; ++trial) {
    const Vec3 d = random_direction(rng);
    sh_basis(4, d, y);
    const double x2 = d.x * d.x, y2 = d.y * d.y, z2 = d.z * d.z;
    EXPECT_NEAR(y[sh_index(4, 0)], 3.0 / (16.0 * std::sqrt(kPi)) * (35.0 * z2 * z2 - 30.0 * z2 + 3.0), 1e-13);
    EXPECT_NEAR(y[sh_index(4, 4)], 3.0 / 16.0 * std::sqrt(35.0 / kPi) * (x2 * x2 - 6.0 * x2 * y2 + y2 * y2), 1e-13);
    EXPECT_NEAR(y[sh_index(4, -4)], 0.75 * std::sqrt(35.0 / kPi) * d.x * d.y * (x2 - y2), 1e-13);
  }
}

TEST(ShBasis, ClosedFormBandsEqualTheRecurrence) {
  // Order 4 evaluates every band by the recurrence; orders <= 3 by the polynomials.
  std::mt19937 rng(11);
  double low[sh_count(3)], high[sh_count(4)];
  for (int trial = 0; trial < 100; ++trial) {
    const Vec3 d = random_direction(rng);
    sh_basis(3, d, low);
    sh_basis(4, d, high);
    for (int i = 0; i < sh_count(3); ++i) EXPECT_NEAR(low[i], high[i], 1e-14) << i;
  }
}

TEST(ShBasis, ZonalRotationEvaluatesTheLobeAroundItsAxis) {
  // A zonal function f(cos t) = exp(3 cos t) projected on bands 0..order, turned to an axis, evaluates at d to the
  // same truncated series at the angle between axis and d: sum_l z_l sqrt((2l+1)/(4 pi)) P_l(axis . d).
  const int order = 8;
  std::vector<double> zonal(order + 1, 0.0), c(sh_count(order)), y(sh_count(order));
  for (int l = 0; l <= order; ++l)
    detail::for_nodes(-1.0, 1.0, 40, [&](double t, double w) {
      zonal[l] += 2.0 * kPi * w * std::exp(3.0 * t) * std::sqrt((2.0 * l + 1.0) / (4.0 * kPi)) * std::legendre(l, t);
    });
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    const Vec3 axis = random_direction(rng), d = random_direction(rng);
    sh_rotate_zonal(order, zonal.data(), axis, c.data());
    sh_basis(order, d, y.data());
    double rotated = 0.0, expected = 0.0;
    for (int i = 0; i < sh_count(order); ++i) rotated += c[i] * y[i];
    for (int l = 0; l <= order; ++l)
      expected += zonal[l] * std::sqrt((2.0 * l + 1.0) / (4.0 * kPi)) * std::legendre(l, axis ^ d);
    EXPECT_NEAR(rotated, expected, 1e-10);
    EXPECT_NEAR(expected, std::exp(3.0 * (axis ^ d)), 0.05 * std::exp(3.0));  // the series converges to f
  }
}

TEST(ShBasis, OrderIsClampedNotOverrun) {
  std::vector<double> y(sh_count(kMaxShOrder) + 1, -7.0);
  sh_basis(kMaxShOrder + 5, Vec3(0, 0, 1), y.data());
  EXPECT_EQ(y.back(), -7.0);  // nothing written past the highest order's coefficients
}

}  // namespace
