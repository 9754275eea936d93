// The DFG LUT against an independent integration: a plain midpoint grid over
// the light direction's spherical coordinates (no importance sampling, no
// half-vector change of variables), to 1e-3.
#include <envkit/core/error.h>
#include <envkit/core/vec.h>
#include <envkit/ibl/dfg.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace envkit;

namespace {

struct Brute {
  double a = 0.0, b = 0.0, s = 0.0;
};

// Integrates over l in spherical coordinates about n = +z (theta_l midpoints in
// cos, phi midpoints).
Brute brute_force(double nv, double r, int nt = 3000, int np = 600) {
  const Vec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);
  const double alpha = r * r, a2 = alpha * alpha;
  const double k = 1.0 / std::max(alpha, 1e-3);
  Brute out;
  for (int t = 0; t < nt; ++t) {
    const double ct = (t + 0.5) / nt, st = std::sqrt(1.0 - ct * ct);
    for (int p = 0; p < np; ++p) {
      const double phi = kTwoPi * (p + 0.5) / np;
      const Vec3 l(st * std::cos(phi), st * std::sin(phi), ct);
      const Vec3 h = (l + v).normalized();
      const double nh = h.z, vh = v ^ h, nl = ct;
      // GGX D, Smith height-correlated G2 / (4 n.l n.v) written from the Lambda
      // form.
      const double d = a2 / (kPi * std::pow(nh * nh * (a2 - 1.0) + 1.0, 2.0));
      auto lambda = [&](double c) { return 0.5 * (-1.0 + std::sqrt(1.0 + a2 * (1.0 - c * c) / (c * c))); };
      const double g2 = 1.0 / (1.0 + lambda(nv) + lambda(nl));
      const double f = d * g2 / (4.0 * nl * nv) * nl;
      const double fc = std::pow(1.0 - vh, 5.0);
      const double dw = (1.0 / nt) * (kTwoPi / np);  // d omega = d(cos theta) d phi
      out.a += f * (1.0 - fc) * dw;
      out.b += f * fc * dw;
      const double sh = std::sqrt(std::max(0.0, 1.0 - nh * nh));
      const double dc = (2.0 + k) * std::pow(sh, k) / kTwoPi;
      out.s += dc / (4.0 * (nl + nv - nl * nv)) * nl * dw;
    }
  }
  return out;
}

TEST(PrefilterDfg, MatchesIndependentIntegration) {
  for (double nv : {0.1, 0.5, 0.9}) {
    for (double r : {0.3, 0.6, 1.0}) {
      const DfgValue d = dfg_integrate(nv, r);
      const Brute b = brute_force(nv, r);
      EXPECT_NEAR(d.scale, b.a, 1e-3) << nv << " " << r;
      EXPECT_NEAR(d.bias, b.b, 1e-3) << nv << " " << r;
      EXPECT_NEAR(d.sheen, b.s, 1e-3) << nv << " " << r;
    }
  }
}

// The default quadrature against eight times its nodes, over the LUT's whole range, grazing views and sharp lobes
// included (where the visible azimuth range changes fastest).
TEST(PrefilterDfg, DefaultQuadratureHasConverged) {
  double worst = 0.0;
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j) {
      const double nv = (8 * i + 0.5) / 128, r = (8 * j + 0.5) / 128;
      const DfgValue d = dfg_integrate(nv, r), fine = dfg_integrate(nv, r, 128, 64);
      worst = std::max(
          {worst, std::abs(d.scale - fine.scale), std::abs(d.bias - fine.bias), std::abs(d.sheen - fine.sheen)});
    }
  EXPECT_LE(worst, 1e-4);
}

TEST(PrefilterDfg, SmoothSurfaceReflectsEverything) {
  // r -> 0: A + B -> 1 (all energy reflected, Fresnel weights sum to 1); B ->
  // (1 - n.v)^5.
  const DfgValue d = dfg_integrate(0.7, 0.02);
  EXPECT_NEAR(d.albedo(), 1.0, 2e-3);
  EXPECT_NEAR(d.bias, std::pow(0.3, 5.0), 1e-3);
  // Rough surfaces lose energy to multiple scattering: E < 1 and the
  // compensation is positive.
  EXPECT_LT(dfg_integrate(0.5, 1.0).albedo(), 0.9);
  EXPECT_GT(dfg_integrate(0.5, 1.0).energy_compensation(), 0.1);
}

TEST(PrefilterDfg, LutTexelsAndLayouts) {
  DfgOptions o;
  o.width = 16;
  o.height = 8;
  const Image lut = dfg_lut(o);
  ASSERT_EQ(lut.width, 16);
  ASSERT_EQ(lut.height, 8);
  const DfgValue d = dfg_integrate((3 + 0.5) / 16, (5 + 0.5) / 8);
  EXPECT_FLOAT_EQ(lut.at(3, 5, 0), float(d.scale));
  EXPECT_FLOAT_EQ(lut.at(3, 5, 1), float(d.bias));
  EXPECT_FLOAT_EQ(lut.at(3, 5, 2), float(d.sheen));
  o.layout = DfgLayout::Filament;
  const Image fil = dfg_lut(o);
  EXPECT_FLOAT_EQ(fil.at(3, 5, 0), float(d.bias));
  EXPECT_FLOAT_EQ(fil.at(3, 5, 1), float(d.albedo()));
  EXPECT_EQ(fil.metadata.at("envkit:dfg_layout"), "filament");
  EXPECT_THROW(parse_dfg_layout("cmft"), Error);
}

}  // namespace
