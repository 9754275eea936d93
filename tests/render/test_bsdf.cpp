// Materials of the renderer (renderer/include/envkit/render/material.h) and the shading frame (frame.h):
// chi-square of sample() against pdf() on the sphere, pdf normalisation, sample/eval/pdf consistency,
// reciprocity, energy, the diffuse albedo, the mirror's delta lobe, and no NaN at grazing or invalid inputs.
#include <chi2.h>
#include <envkit/render/frame.h>
#include <envkit/render/material.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../../renderer/src/material_microfacet.h"  // private helpers: the fast conductor Fresnel is checked
#include "bsdf_support.h"

namespace envkit::render {
namespace {

using testmaps::uniform53;

using namespace bsdf_test;

// ---------------------------------------------------------------------------------------------------------------
// The materials under test.

struct MaterialCase {
  std::string name;  // gtest-safe
  std::function<std::unique_ptr<Material>()> make;
};

void PrintTo(const MaterialCase& c, std::ostream* os) { *os << c.name; }

const Vec3 kGoldEta(0.143, 0.374, 1.442), kGoldK(3.983, 2.385, 1.603);

std::vector<MaterialCase> non_delta_cases() {
  std::vector<MaterialCase> cases;
  cases.push_back({"Diffuse", [] { return make_diffuse(Vec3(0.8, 0.5, 0.2)); }});
  for (double r : {0.01, 0.05, 0.2, 0.5, 1.0}) {
    const std::string tag = std::to_string(int(std::lround(r * 100)));
    cases.push_back({"ConductorR" + tag, [r] { return make_conductor(kGoldEta, kGoldK, r); }});
    cases.push_back({"PlasticR" + tag, [r] { return make_plastic(Vec3(0.6, 0.3, 0.1), r, 1.5); }});
  }
  for (double r : {0.2, 0.5})
    cases.push_back({"ConductorSeparableR" + std::to_string(int(std::lround(r * 100))),
                     [r] { return make_conductor(kGoldEta, kGoldK, r, Shadowing::Separable); }});
  return cases;
}

constexpr double kWoAngles[] = {0.0, 30.0, 60.0, 85.0};
constexpr int kChi2Tests = 13 * 4;  // cases x wo angles, for the Sidak correction

class BsdfChi2 : public ::testing::TestWithParam<MaterialCase> {};

// For each wo: histogram of sample() directions on the sphere grid against N x the integral of pdf() over each cell;
// samples with pdf 0 or in a cell of expected count 0 fail. Also: the integral of pdf over the sphere equals the
// fraction of sample() calls that succeed (1 where no sample is lost) and never exceeds 1.
TEST_P(BsdfChi2, SampleMatchesPdf) {
  const auto material = GetParam().make();
  const SphereGrid grid;
  constexpr std::size_t n = 400000;
  for (double theta_o : kWoAngles) {
    SCOPED_TRACE("wo theta = " + std::to_string(theta_o));
    const Vec3 wo = wo_at(theta_o);
    std::mt19937_64 rng(1234 + std::uint64_t(theta_o));
    std::vector<double> observed(std::size_t(grid.cells()), 0.0);
    std::size_t ok = 0, bad = 0;
    for (std::size_t i = 0; i < n; ++i) {
      BsdfSample s;
      const Vec2 u(uniform53(rng), uniform53(rng));
      if (!material->sample(wo, u, uniform53(rng), s)) continue;
      if (!(s.pdf > 0.0) || !finite3(s.wi) || std::abs(s.wi.length() - 1.0) > 1e-9) {
        ++bad;
        continue;
      }
      ++ok;
      observed[std::size_t(grid.cell_of(s.wi))] += 1.0;
    }
    EXPECT_EQ(bad, 0u);
    const std::vector<double> mass = integrate_cells(
        grid, [&](const Vec3& wi) { return material->pdf(wo, wi); }, 1e-9);
    double total = 0.0;
    for (double m : mass) total += m;
    const double accepted = double(ok) / double(n);
    EXPECT_LE(total, 1.0 + 1e-4);
    // The pdf integrates to the probability that sample() returns a direction (1 when nothing is lost).
    EXPECT_NEAR(total, accepted, 4.0 * std::sqrt(accepted * (1.0 - accepted) / double(n)) + 2e-4);
    if (GetParam().name == "Diffuse") {
      EXPECT_NEAR(total, 1.0, 1e-6);
    }
    std::vector<double> expected(mass.size());
    for (std::size_t c = 0; c < mass.size(); ++c) expected[c] = mass[c] * double(n);
    const chi2::Result r = chi2::test(observed, expected, chi2::sidak_alpha(0.01, kChi2Tests));
    EXPECT_TRUE(r.passed) << r.message;
  }
}

// sample() returns f_cos == eval(wo, wi) and pdf == pdf(wo, wi): the estimator weight f_cos / pdf is the same
// whichever way it is computed (what MIS needs).
TEST_P(BsdfChi2, SampleAgreesWithEvalAndPdf) {
  const auto material = GetParam().make();
  std::mt19937_64 rng(99);
  for (double theta_o : {0.0, 10.0, 45.0, 80.0, 89.9}) {
    const Vec3 wo = wo_at(theta_o, 77.0);
    for (int i = 0; i < 20000; ++i) {
      BsdfSample s;
      if (!material->sample(wo, Vec2(uniform53(rng), uniform53(rng)), uniform53(rng), s)) continue;
      ASSERT_FALSE(s.is_delta);
      const Vec3 f = material->eval(wo, s.wi);
      const double p = material->pdf(wo, s.wi);
      ASSERT_GT(p, 0.0);
      ASSERT_NEAR(s.pdf, p, 1e-9 * p);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.f_cos[c], f[c], 1e-9 * std::max(f[c], 1e-300));
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.f_cos[c] / s.pdf, f[c] / p, 1e-9 * f[c] / p + 1e-300);
    }
  }
}

// f(wo, wi) = f(wi, wo): eval(wo, wi) / cos_i == eval(wi, wo) / cos_o.
TEST_P(BsdfChi2, Reciprocity) {
  const auto material = GetParam().make();
  std::mt19937_64 rng(7);
  for (int i = 0; i < 20000; ++i) {
    const Vec3 a = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));
    const Vec3 b = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));
    if (a.z < 1e-6 || b.z < 1e-6) continue;
    const Vec3 fab = material->eval(a, b) / b.z, fba = material->eval(b, a) / a.z;
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(fab[c], fba[c], 1e-9 * std::max(std::abs(fab[c]), 1e-12));
  }
}

// Grazing, below-horizon, opposite and non-finite directions: nothing returns NaN or inf.
TEST_P(BsdfChi2, NoNanAtEdges) {
  const auto material = GetParam().make();
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Vec3> dirs = {Vec3(0, 0, 1),      Vec3(1, 0, 0),
                                  Vec3(0, 0, -1),     Vec3(1, 0, 1e-300),
                                  Vec3(1, 0, 1e-12),  Vec3(-1, 0, 1e-12),
                                  Vec3(0, 1, -1e-12), Vec3(0.6, 0, 0.8),
                                  Vec3(-0.6, 0, 0.8), Vec3(0, 0, 0),
                                  Vec3(nan, 0, 1),    Vec3(0, inf, 1),
                                  Vec3(1, 0, 5e-324), Vec3(0.999999, 0, std::sqrt(1 - 0.999999 * 0.999999))};
  const double us[] = {0.0, 1e-300, 0.5, kOneMinusEpsilon, 1.0, nan};
  for (const Vec3& wo : dirs) {
    for (const Vec3& wi : dirs) {
      const Vec3 f = material->eval(wo, wi);
      const double p = material->pdf(wo, wi);
      ASSERT_TRUE(finite3(f) && f.x >= 0 && f.y >= 0 && f.z >= 0) << "eval " << wo << " " << wi;
      ASSERT_TRUE(std::isfinite(p) && p >= 0.0) << "pdf " << wo << " " << wi;
      if (!(wo.z > 0.0) || !(wi.z > 0.0)) {
        ASSERT_EQ(p, 0.0);
        ASSERT_EQ(f, Vec3(0.0));
      }
    }
    for (double a : us)
      for (double b : us)
        for (double l : us) {
          BsdfSample s;
          if (material->sample(wo, Vec2(a, b), l, s)) {
            ASSERT_TRUE(wo.z > 0.0);
            ASSERT_TRUE(finite3(s.wi) && finite3(s.f_cos) && std::isfinite(s.pdf) && s.pdf > 0.0)
                << "sample " << wo << " u " << a << "," << b;
            ASSERT_GT(s.wi.z, 0.0);
          }
        }
  }
}

struct CaseName {
  std::string operator()(const ::testing::TestParamInfo<MaterialCase>& param_info) const {
    return param_info.param.name;
  }
};
INSTANTIATE_TEST_SUITE_P(Materials, BsdfChi2, ::testing::ValuesIn(non_delta_cases()), CaseName());

// ---------------------------------------------------------------------------------------------------------------
// Energy.

// Directional albedo of the non-delta part: integral of eval over the sphere (adaptive quadrature).
Vec3 albedo_quadrature(const Material& m, const Vec3& wo, int channels = 3, double tol = 1e-6) {
  const SphereGrid grid{8, 16};
  Vec3 a(0.0);
  for (int c = 0; c < channels; ++c) {
    double s = 0.0;
    for (double v : integrate_cells(
             grid, [&](const Vec3& wi) { return m.eval(wo, wi)[c]; }, tol))
      s += v;
    a[c] = s;
  }
  return a;
}

// Monte Carlo albedo with the material's own sampling: mean of f_cos / pdf (mean and standard error, channel 0).
void albedo_sampled(const Material& m, const Vec3& wo, std::size_t n, double& mean, double& sigma) {
  std::mt19937_64 rng(5);
  double s = 0.0, s2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    BsdfSample b;
    double w = 0.0;
    if (m.sample(wo, Vec2(uniform53(rng), uniform53(rng)), uniform53(rng), b)) w = b.f_cos.x / b.pdf;
    s += w;
    s2 += w * w;
  }
  mean = s / double(n);
  sigma = std::sqrt(std::max(0.0, s2 / double(n) - mean * mean) / double(n));
}

TEST(BsdfEnergy, DiffuseAlbedoIsRho) {
  const Vec3 rho(0.8, 0.5, 0.2);
  const auto m = make_diffuse(rho);
  for (double theta_o : {0.0, 45.0, 89.0}) {
    const Vec3 a = albedo_quadrature(*m, wo_at(theta_o));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], rho[c], 1e-3) << "theta_o " << theta_o;
  }
}

// A white conductor (eta = 0, k > 0: F = 1 exactly) loses energy only to masking: its albedo is <= 1 at every
// roughness and -> 1 as alpha -> 0 (G2 -> 1).
TEST(BsdfEnergy, WhiteConductorAlbedo) {
  for (double r : {0.01, 0.05, 0.1, 0.3, 0.6, 1.0}) {
    const auto m = make_conductor(Vec3(0.0), Vec3(1.0), r);
    for (double theta_o : {0.0, 30.0, 60.0, 80.0}) {
      SCOPED_TRACE("roughness " + std::to_string(r) + " theta_o " + std::to_string(theta_o));
      const Vec3 wo = wo_at(theta_o);
      double mean = 0.0, sigma = 0.0;
      albedo_sampled(*m, wo, 200000, mean, sigma);
      EXPECT_LE(mean, 1.0 + 1e-9);  // every weight F G2 / G1 is <= 1
      if (r >= 0.1) {
        const double q = albedo_quadrature(*m, wo, 1).x;
        EXPECT_LE(q, 1.0 + 1e-4);
        EXPECT_NEAR(q, mean, 4.0 * sigma + 1e-3);
      }
      if (r <= 0.05 && theta_o <= 60.0) {
        EXPECT_NEAR(mean, 1.0, 0.02);
      }
    }
  }
}

// The separable masking-shadowing G1(wo) G1(wi) is never above the height-correlated G2 (a product of two factors
// 1 / (1 + Lambda) against 1 / (1 + Lambda_o + Lambda_i)), equals it where either direction is the normal
// (Lambda = 0), and at wo = wi, both at 60 degrees from the normal with alpha = 0.5, has its closed form:
// G1 = 2 cos / (cos + sqrt(alpha^2 + (1 - alpha^2) cos^2)), so separable / height-correlated = G1^2 (1 + 2 Lambda).
TEST(BsdfEnergy, SeparableShadowingIsNeverBrighter) {
  for (double r : {0.05, 0.3, 1.0}) {
    const auto correlated = make_conductor(kGoldEta, kGoldK, r);
    const auto separable = make_conductor(kGoldEta, kGoldK, r, Shadowing::Separable);
    std::mt19937_64 rng(7);
    for (int k = 0; k < 2000; ++k) {
      const Vec3 wo = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));  // uniform on the upper hemisphere
      const Vec3 wi = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));
      const Vec3 a = separable->eval(wo, wi), b = correlated->eval(wo, wi);
      ASSERT_LE(a.x, b.x * (1.0 + 1e-12)) << r << " " << k;
      ASSERT_EQ(separable->pdf(wo, wi), correlated->pdf(wo, wi)) << r << " " << k;  // the same sampling
    }
    const Vec3 n(0, 0, 1), w = wo_at(50.0);
    EXPECT_NEAR(separable->eval(n, w).y, correlated->eval(n, w).y, 1e-12 * correlated->eval(n, w).y);
  }
  const double alpha = 0.5, c = 0.5;  // cos 60 degrees
  const double root = std::sqrt(alpha * alpha + (1.0 - alpha * alpha) * c * c);
  const double g1 = 2.0 * c / (c + root), lambda = 0.5 * (root / c - 1.0);
  const Vec3 wo = wo_at(60.0), wi(-wo.x, -wo.y, wo.z);  // the mirror direction: h = n
  const double ratio = make_conductor(kGoldEta, kGoldK, alpha, Shadowing::Separable)->eval(wo, wi).y /
                       make_conductor(kGoldEta, kGoldK, alpha)->eval(wo, wi).y;
  EXPECT_NEAR(ratio, g1 * g1 * (1.0 + 2.0 * lambda), 1e-12);  // 0.981
  EXPECT_LT(ratio, 0.99);
}

// Plastic with a white base: coat + base never reflect more than comes in (up to the small excess of the rough
// coat's F(wo.h) over F(cos_o) that the layering model does not account for).
TEST(BsdfEnergy, PlasticAlbedoAtMostOne) {
  for (double r : {0.01, 0.1, 0.5, 1.0}) {
    const auto m = make_plastic(Vec3(1.0), r, 1.5);
    for (double theta_o : {0.0, 45.0, 80.0}) {
      double mean = 0.0, sigma = 0.0;
      albedo_sampled(*m, wo_at(theta_o), 200000, mean, sigma);
      EXPECT_LE(mean, 1.0 + 0.01 + 4.0 * sigma) << "roughness " << r << " theta_o " << theta_o;
      EXPECT_GT(mean, 0.5);
    }
  }
  // A black base leaves only the coat: the albedo of a smooth coat at normal incidence is F(0) = 0.04.
  const auto coat = make_plastic(Vec3(0.0), 0.01, 1.5);
  double mean = 0.0, sigma = 0.0;
  albedo_sampled(*coat, Vec3(0, 0, 1), 100000, mean, sigma);
  EXPECT_NEAR(mean, 0.04, 1e-3);
}

// Fresnel of gold at normal incidence, ((n-1)^2 + k^2) / ((n+1)^2 + k^2), through a very smooth conductor's albedo.
TEST(BsdfEnergy, ConductorFresnelAtNormalIncidence) {
  const auto m = make_conductor(kGoldEta, kGoldK, 0.001);
  double mean = 0.0, sigma = 0.0;
  albedo_sampled(*m, Vec3(0, 0, 1), 20000, mean, sigma);
  const double n = kGoldEta.x, k = kGoldK.x;
  const double f0 = ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k);
  EXPECT_NEAR(mean, f0, 2e-3);
}

// The real-arithmetic conductor Fresnel equals the std::complex reference, and the dielectric one gives the
// textbook values.
TEST(BsdfFresnel, ConductorMatchesComplexReference) {
  for (double eta : {0.0, 0.05, 0.143, 0.2, 1.0, 1.5, 3.0})
    for (double k : {0.0, 0.5, 1.0, 2.385, 3.983, 8.0})
      for (int i = 0; i <= 200; ++i) {
        const double c = i / 200.0;
        EXPECT_NEAR(detail::fresnel_conductor(c, eta, k), detail::fresnel_conductor_complex(c, eta, k), 1e-12)
            << "eta " << eta << " k " << k << " cos " << c;
      }
  EXPECT_NEAR(detail::fresnel_conductor(0.3, 0.0, 2.0), 1.0, 1e-14);  // eta = 0: a white conductor
  EXPECT_NEAR(detail::fresnel_dielectric(1.0, 1.5), 0.04, 1e-15);
  EXPECT_NEAR(detail::fresnel_dielectric(0.0, 1.5), 1.0, 1e-15);
}

// ---------------------------------------------------------------------------------------------------------------
// Mirror.

TEST(BsdfMirror, ReflectsAndIsDelta) {
  const auto m = make_mirror(Vec3(0.9, 0.8, 0.7));
  EXPECT_TRUE(m->has_delta());
  EXPECT_TRUE(m->is_pure_delta());
  const Vec3 wo = wo_at(40.0, 10.0);
  BsdfSample s;
  ASSERT_TRUE(m->sample(wo, Vec2(0.3, 0.7), 0.2, s));
  EXPECT_TRUE(s.is_delta);
  EXPECT_NEAR(s.wi.x, -wo.x, 1e-15);
  EXPECT_NEAR(s.wi.y, -wo.y, 1e-15);
  EXPECT_NEAR(s.wi.z, wo.z, 1e-15);
  EXPECT_EQ(s.pdf, 1.0);
  EXPECT_EQ(s.f_cos, Vec3(0.9, 0.8, 0.7));
  EXPECT_EQ(m->eval(wo, s.wi), Vec3(0.0));
  EXPECT_EQ(m->pdf(wo, s.wi), 0.0);
  EXPECT_FALSE(m->sample(Vec3(0, 0.6, -0.8), Vec2(0.3, 0.7), 0.2, s));
  EXPECT_FALSE(make_diffuse(Vec3(1))->has_delta());
  EXPECT_FALSE(make_conductor(kGoldEta, kGoldK, 0.1)->is_pure_delta());
}

// ---------------------------------------------------------------------------------------------------------------
// Frame.

TEST(ShadingFrame, OrthonormalAndRoundTrip) {
  std::mt19937_64 rng(3);
  std::vector<Vec3> normals = {Vec3(0, 0, 1),
                               Vec3(0, 0, -1),
                               Vec3(1, 0, 0),
                               Vec3(0, -1, 0),
                               Vec3(0, 1e-9, -1).normalized(),
                               Vec3(1e-17, 0, -1).normalized()};
  for (int i = 0; i < 1000; ++i) normals.push_back(direction_zphi(2.0 * uniform53(rng) - 1.0, kTwoPi * uniform53(rng)));
  for (const Vec3& n : normals) {
    const Frame f = Frame::from_normal(n);
    EXPECT_NEAR(f.s.length(), 1.0, 1e-12);
    EXPECT_NEAR(f.t.length(), 1.0, 1e-12);
    EXPECT_NEAR(f.s ^ f.t, 0.0, 1e-12);
    EXPECT_NEAR(f.s ^ f.n, 0.0, 1e-12);
    EXPECT_NEAR(f.t ^ f.n, 0.0, 1e-12);
    EXPECT_NEAR(((f.s % f.t) - f.n).length(), 0.0, 1e-12);  // right-handed
    const Vec3 local = f.to_local(n);
    EXPECT_NEAR(local.z, 1.0, 1e-12);
    const Vec3 v(0.3, -0.2, 0.9);
    EXPECT_NEAR((f.to_world(f.to_local(v)) - v).length(), 0.0, 1e-12);
  }
  const Frame bad = Frame::from_normal(Vec3(0.0));
  EXPECT_TRUE(finite3(bad.s) && finite3(bad.t) && finite3(bad.n));
}

}  // namespace
}  // namespace envkit::render
