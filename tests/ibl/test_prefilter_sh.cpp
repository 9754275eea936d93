// Spherical harmonics and irradiance maps against closed forms: orthonormality,
// a constant map (E = pi L), a sky gradient (exact in bands 0-1), a single sun
// (E = F max(0, n.s) and its SH truncation by Legendre sums).
#include <envkit/core/error.h>
#include <envkit/core/gauss_legendre.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/ibl/sh.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <nlohmann/json.hpp>

#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;

namespace {

TEST(PrefilterSh, BasisIsOrthonormal) {
  // Project each basis function (rasterised on a fine lat-long) and read back a
  // unit vector.
  const int order = 3;
  for (int i = 0; i < sh_count(order); ++i) {
    const EnvMap map = latlong_env(512, [&](const Vec3& d) {
      double y[16];
      sh_basis(order, d, y);
      return Vec3(y[i]);
    });
    const ShCoefficients sh = project_sh(map.ref(), order);
    for (int j = 0; j < sh_count(order); ++j) EXPECT_NEAR(sh.radiance[0][j], i == j ? 1.0 : 0.0, 2e-4) << i << " " << j;
  }
}

TEST(PrefilterSh, ConstantMapGivesPiL) {
  // Texel-centre quadrature of Y_20 over a 512 x 256 lat-long leaves ~1e-5 of L
  // in band 2.
  const EnvMap map = latlong_env(512, [](const Vec3&) { return Vec3(0.5, 1.0, 2.0); });
  const ShCoefficients sh = project_sh(map.ref(), 2);
  for (const Vec3& n : {Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0.3, -0.4, 0.866).normalized()}) {
    EXPECT_NEAR(sh.eval_irradiance(0, n) * kPi, kPi * 0.5, 1e-4 * kPi * 0.5);
    EXPECT_NEAR(sh.eval_irradiance(2, n) * kPi, kPi * 2.0, 1e-4 * kPi * 2.0);
  }
  EXPECT_NEAR(sh.radiance[1][0], 1.0 * std::sqrt(4.0 * kPi),
              1e-9);  // L_00 = L sqrt(4 pi)
  const EnvMap irr = irradiance_map(map.ref(), {});
  for (std::size_t i = 0; i < irr.image.texel_count(); ++i) EXPECT_NEAR(irr.image.pixels[i * 3 + 1], 1.0, 1e-5);
}

TEST(PrefilterSh, SkyGradientIsExactInTheFirstTwoBands) {
  // L = a + b y: E(n) = pi a + (2 pi / 3) b n_y exactly; SH of order 2 and 3
  // represent it exactly.
  const double a = 1.0, b = 0.6;
  const EnvMap map = latlong_env(256, [&](const Vec3& d) { return Vec3(a + b * d.y); });
  IrradianceOptions io;
  io.size = 8;
  const EnvMap irr = irradiance_map(map.ref(), io);
  const TexelDirections dirs(*irr.param);
  for (int order : {2, 3}) {
    const ShCoefficients sh = project_sh(map.ref(), order);
    for (int y = 0; y < irr.image.height; ++y)
      for (int x = 0; x < irr.image.width; ++x) {
        Vec3 n;
        dirs.centre(x, y, n);
        const double exact = a + 2.0 / 3.0 * b * n.y;  // E / pi
        EXPECT_NEAR(sh.eval_irradiance(0, n), exact, 2e-4);
        EXPECT_NEAR(irr.image.at(x, y, 0), exact, 2e-3 * exact);
      }
  }
}

TEST(PrefilterSh, SingleSunMatchesClosedForms) {
  EnvMap map = latlong_env(256, [](const Vec3&) { return Vec3(0.0); });
  const int sx = 40, sy = 30;
  for (int c = 0; c < 3; ++c) map.image.at(sx, sy, c) = 1e6f;
  Vec3 s;
  TexelDirections(*map.param).centre(sx, sy, s);
  const double flux = 1e6 * map.param->texel_solid_angle(sx, sy);
  const ShCoefficients sh = project_sh(map.ref(), 2);
  // Radiance SH: L_lm = F Y_lm(s).
  double ys[16];
  sh_basis(2, s, ys);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(sh.radiance[0][i], flux * ys[i], 1e-9 * flux);
  // Irradiance of the truncated SH: E(n) = F sum_l A_l (2l + 1) / (4 pi)
  // P_l(n.s) (addition theorem).
  const ShCoefficients windowed = project_sh(map.ref(), 2, ShWindow::Hanning);
  for (const Vec3& n : {s, Vec3(0, 1, 0), Vec3(-s.x, 0.2, -s.z).normalized()}) {
    const double t = n ^ s;
    const double p[3] = {1.0, t, 0.5 * (3.0 * t * t - 1.0)};
    double e = 0.0, ew = 0.0;
    for (int l = 0; l < 3; ++l) {
      e += flux * sh_cosine_lobe(l) * (2 * l + 1) / (4.0 * kPi) * p[l];
      ew += flux * sh_cosine_lobe(l) * sh_window_factor(ShWindow::Hanning, l, 2) * (2 * l + 1) / (4.0 * kPi) * p[l];
    }
    EXPECT_NEAR(sh.eval_irradiance(0, n) * kPi, e, 1e-6 * flux);
    EXPECT_NEAR(windowed.eval_irradiance(0, n) * kPi, ew, 1e-6 * flux);
  }
  // Hanning w_l = (1 + cos(pi l / 3)) / 2: 1, 3/4, 1/4.
  EXPECT_NEAR(sh_window_factor(ShWindow::Hanning, 1, 2), 0.75, 1e-12);
  EXPECT_NEAR(sh_window_factor(ShWindow::Hanning, 2, 2), 0.25, 1e-12);
  // Exact convolution: E(n) / pi = F max(0, n.s) / pi at every texel of the
  // irradiance map.
  IrradianceOptions io;
  io.size = 8;
  const EnvMap irr = irradiance_map(map.ref(), io);
  const TexelDirections dirs(*irr.param);
  for (int y = 0; y < irr.image.height; ++y)
    for (int x = 0; x < irr.image.width; ++x) {
      Vec3 n;
      dirs.centre(x, y, n);
      EXPECT_NEAR(irr.image.at(x, y, 0), flux * std::max(0.0, n ^ s) / kPi, 2e-3 * flux / kPi);
    }
}

TEST(PrefilterSh, JsonSpellsOutTheNormalisation) {
  const EnvMap map = latlong_env(32, [](const Vec3& d) { return Vec3(1.0 + d.y); });
  const nlohmann::json j = project_sh(map.ref(), 3, ShWindow::Lanczos).to_json();
  EXPECT_EQ(j.at("coefficients_per_channel"), 16);
  EXPECT_EQ(j.at("window"), "lanczos");
  EXPECT_EQ(j.at("radiance").at("coefficients").at("R").size(), 16u);
  const double c0 = j.at("irradiance").at("coefficients").at("G")[0];
  const double c0_pi = j.at("irradiance_over_pi").at("coefficients").at("G")[0];
  EXPECT_NEAR(c0, kPi * c0_pi, 1e-12);
  EXPECT_DOUBLE_EQ(j.at("cosine_lobe_A_l")[3], 0.0);
  EXPECT_THROW(project_sh(map.ref(), kMaxShOrder + 1), Error);
  EXPECT_THROW(project_sh(map.ref(), 0), Error);
}

TEST(PrefilterSh, HighOrderProjectionReconstructsABandLimitedMap) {
  // A map that is a sum of band-6 and band-2 functions comes back as its coefficients, and eval_radiance rebuilds it.
  const int order = 6;
  auto f = [](const Vec3& d) {
    double y[sh_count(6)];
    sh_basis(6, d, y);
    return Vec3(0.3 * y[sh_index(6, -5)] + 0.2 * y[sh_index(2, 1)] + 0.1 * y[0]);
  };
  const EnvMap map = latlong_env(512, f);
  const ShCoefficients sh = project_sh(map.ref(), order);
  for (int i = 0; i < sh_count(order); ++i) {
    const double expected = i == sh_index(6, -5) ? 0.3 : i == sh_index(2, 1) ? 0.2 : i == 0 ? 0.1 : 0.0;
    EXPECT_NEAR(sh.radiance[0][i], expected, 2e-4) << i;
  }
  for (const Vec3& n : {Vec3(0, 1, 0), Vec3(0.6, 0.0, 0.8), Vec3(-0.48, 0.6, -0.64)})
    EXPECT_NEAR(sh.eval_radiance(0, n), f(n).x, 2e-3);
}

TEST(PrefilterSh, CosineLobeFactorsMatchTheirIntegrals) {
  // A_l = 2 pi integral_0^1 z P_l(z) dz (the clamped cosine's zonal coefficients, times sqrt(4 pi / (2l + 1))).
  for (int l = 0; l <= kMaxShOrder; ++l) {
    double a = 0.0;
    detail::for_nodes(0.0, 1.0, 24, [&](double z, double w) { a += 2.0 * kPi * w * z * std::legendre(l, z); });
    EXPECT_NEAR(sh_cosine_lobe(l), a, 1e-12) << l;
  }
}

TEST(PrefilterSh, IndependentOfThreadCount) {
  const EnvMap map = latlong_env(128, smooth_sky);
  const ShCoefficients many = project_sh(map.ref(), 3);
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  EXPECT_EQ(project_sh(map.ref(), 3).radiance, many.radiance);
}

}  // namespace
