// A single shading point: the direct-light estimator of every strategy against a numerically integrated
// reference  integral f(wo, wi) cos(theta_i) L(wi) d wi  (quadrature over the environment's own texels).
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/frame.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

constexpr int kW = 64, kH = 32;

struct Environment {
  EnvMap map;
  std::shared_ptr<const EnvTables> tables;
  std::unique_ptr<EnvironmentLight> light;
  int width, height;
  Environment(const probes::Probe& probe, const Mat3& rotation, int importance_width = 0, int w = kW, int h = kH)
      : width(w), height(h) {
    LatLongMap grid(w, h);
    LoadOptions load;
    load.kind = Kind::LatLong;
    map = make_envmap(probes::rasterize(probe, grid), "probe", load);
    BakeOptions bake;
    bake.compensated = true;
    bake.importance_width = importance_width;
    bake.importance_height = importance_width / 2;
    tables = std::make_shared<EnvTables>(EnvTables::bake(map, bake));
    light = std::make_unique<EnvironmentLight>(map, tables, rotation, 1.0);
  }
};

/// integral of eval(wo, wi) L(wi) over the sphere, L piecewise constant per texel (nearest lookup): each texel
/// is split into k x k cells uniform in longitude and cos theta (equal solid angle), evaluated at cell centres.
Vec3 reference(const Environment& env, const Material& material, const Frame& frame, const Vec3& wo, int k) {
  const EnvironmentLight& light = *env.light;
  const int W = env.width, H = env.height;
  Vec3 sum(0, 0, 0);
  const Mat3& R = light.rotation();
  for (int y = 0; y < H; ++y) {
    const double z0 = std::cos(kPi * y / H), z1 = std::cos(kPi * (y + 1) / H);
    for (int x = 0; x < W; ++x)
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) {
          const double u = (x + (a + 0.5) / k) / W;
          const double z = z0 + (z1 - z0) * (b + 0.5) / k;
          const double d_omega = (kTwoPi / (W * k)) * (z0 - z1) / k;
          const Vec3 table_dir = LatLongMap::direction_from_uv(u, safe_acos(z) / kPi);
          const Vec3 world = apply(R, table_dir);
          const Vec3 wi = frame.to_local(world);
          if (wi.z <= 0.0) continue;
          const Vec3 f = material.eval(wo, wi);
          const Vec3 L = light.radiance(world);
          sum += Vec3(f.x * L.x, f.y * L.y, f.z * L.z) * d_omega;
        }
  }
  return sum;
}

std::vector<IntegratorOptions> strategies() {
  std::vector<IntegratorOptions> list;
  auto add = [&](Strategy s, SamplingMethod m, Heuristic h, int n, int mm) {
    list.push_back(envkit::test::strategy_options(s, m, h, n, mm));
  };
  add(Strategy::Bsdf, SamplingMethod::Cdf, Heuristic::Power, 1, 0);
  add(Strategy::Light, SamplingMethod::Cdf, Heuristic::Power, 0, 1);
  add(Strategy::Light, SamplingMethod::Hierarchical, Heuristic::Power, 0, 1);
  list.back().sun_samples = 2;
  add(Strategy::Light, SamplingMethod::Cdf, Heuristic::Power, 0, 1);
  list.back().sun_samples = 0;
  add(Strategy::Light, SamplingMethod::Alias, Heuristic::Power, 0, 1);
  add(Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Balance, 1, 1);
  add(Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Power, 2, 1);
  add(Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  list.back().sun_samples = 0;
  add(Strategy::Mis, SamplingMethod::Alias, Heuristic::Balance, 1, 2);
  list.back().sun_samples = 3;
  add(Strategy::MisCompensated, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  add(Strategy::MisCompensated, SamplingMethod::Alias, Heuristic::Balance, 1, 1);
  add(Strategy::Product, SamplingMethod::Hierarchical, Heuristic::Power, 0, 1);
  add(Strategy::ProductMis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  add(Strategy::ProductMis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 2);
  list.back().sun_samples = 0;
  list.emplace_back();  // the defaults: product-mis, N and M by the material's lobe
  list.emplace_back();
  list.back().strategy = Strategy::Mis;
  list.back().light_samples = 2;  // N by lobe
  return list;
}

std::string describe(const IntegratorOptions& o) {
  return std::string(strategy_name(o.strategy)) + " " + method_name(o.light_method) +
         " N=" + (o.bsdf_samples ? std::to_string(*o.bsdf_samples) : "lobe") +
         " M=" + (o.light_samples ? std::to_string(*o.light_samples) : "lobe") +
         (o.heuristic == Heuristic::Balance ? " balance" : "") + " sun=" + std::to_string(o.sun_samples);
}

/// Mean and standard error of `n` estimates of direct() at one shading point (luminance-free: per channel).
void estimate(const Integrator& integrator, const Frame& frame, const Material& material, const Vec3& wo, int n,
              Vec3& mean, Vec3& std_error) {
  Vec3 sum(0, 0, 0), sum_sq(0, 0, 0);
  Sampler sampler(1234, 5, 7);
  for (int i = 0; i < n; ++i) {
    sampler.start_sample(std::uint32_t(i));
    const Vec3 v = integrator.direct(Vec3(0, 0, 0), frame, frame.n, wo, material, sampler);
    ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
    sum += v;
    sum_sq += Vec3(v.x * v.x, v.y * v.y, v.z * v.z);
  }
  mean = sum / double(n);
  for (int c = 0; c < 3; ++c) std_error[c] = std::sqrt(std::max(0.0, sum_sq[c] / n - mean[c] * mean[c]) / (n - 1.0));
}

/// Checks every strategy at one shading point; returns how many of them split a sun off (sun_split.h).
int check_point(const probes::Probe& probe, const Mat3& rotation, std::unique_ptr<Material> owned, double tolerance_rel,
                int importance_width = 0, int width = kW, int quadrature = 24) {
  const Environment env(probe, rotation, importance_width, width, width / 2);
  Scene empty;  // nothing occludes; the material is the scene's, so that the product strategies build its tables
  const Material& material = empty.material(empty.add_material("m", std::move(owned)));
  empty.commit();
  const Frame frame = Frame::from_normal(Vec3(0.3, 1.0, -0.2).normalized());
  const Vec3 wo = Vec3(0.35, -0.2, 0.9).normalized();
  const Vec3 ref = reference(env, material, frame, wo, quadrature);
  EXPECT_GT(ref.x + ref.y + ref.z, 0.0);
  int split = 0;
  for (const IntegratorOptions& o : strategies()) {
    const Integrator integrator(empty, *env.light, o);
    split += integrator.sun_split() != nullptr;
    const bool product =
        o.strategy == Strategy::Product || o.strategy == Strategy::ProductMis || o.strategy == Strategy::Auto;
    EXPECT_EQ(integrator.has_product_tables(), product && !material.is_pure_delta()) << describe(o);
    Vec3 mean(0, 0, 0), se(0, 0, 0);
    const char* override_n = std::getenv("ENVKIT_REFERENCE_SAMPLES");  // for manual convergence checks
    estimate(integrator, frame, material, wo, override_n ? std::atoi(override_n) : 4096, mean, se);
    std::printf("  %-45s mean/ref - 1 = %+.2e  (z = %+.2f, relative se %.1e)\n", describe(o).c_str(),
                mean.y / ref.y - 1.0, (mean.y - ref.y) / std::max(se.y, 1e-300), se.y / ref.y);
    for (int c = 0; c < 3; ++c) {
      // Within 4 standard errors, plus the quadrature's own error (relative).
      EXPECT_NEAR(mean[c], ref[c], 4.0 * se[c] + tolerance_rel * ref[c])
          << material.name() << ": " << describe(o) << " channel " << c << " (se " << se[c] << ")";
    }
  }
  return split;
}

}  // namespace

TEST(RenderReference, GlossyConductorUnderASkyGradient) {
  const probes::GradientProbe sky(Vec3(0.2, 0.25, 0.3), Vec3(1.0, 1.5, 2.5));
  check_point(sky, rotation_from_euler_degrees(30, 10, 0),
              make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.1), 0.2), 2e-3);
  check_point(sky, rotation_from_euler_degrees(-60, 20, 0),
              make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.1), 0.4, Shadowing::Separable), 2e-3);
}

TEST(RenderReference, RoughPlasticUnderACheckerboard) {
  const probes::CheckerProbe checker(4, 8, Vec3(2.0, 1.0, 0.5), Vec3(0.1, 0.3, 0.6));
  check_point(checker, identity3(), make_plastic(Vec3(0.6, 0.3, 0.2), 0.1), 2e-3);
}

TEST(RenderReference, GlossyConductorUnderABroadSun) {
  // A sun of 4 degrees radius, 200x the sky: peaky but resolvable by the 64x32 quadrature.
  const probes::SunProbe sun(Vec3(0.2, 0.8, -0.3), probes::radians(4.0), Vec3(200.0), Vec3(0.5));
  check_point(sun, identity3(), make_conductor(Vec3(0.0), Vec3(1.0), 0.15), 3e-3);
}

TEST(RenderReference, DiffuseUnderTheDefaultProbe) {
  const auto probe = probes::make_default_probe();
  check_point(*probe, identity3(), make_diffuse(Vec3(0.8, 0.6, 0.4)), 2e-3);
}

TEST(RenderReference, CoarseImportanceTablesKeepFullResolutionRadiance) {
  // Tables baked with a 16x8 importance (--resolution) over the 64x32 radiance grid: radiance is still looked up
  // on the 64x32 grid and every strategy still converges to the same integral.
  const probes::CheckerProbe checker(8, 16, Vec3(3.0, 1.5, 0.5), Vec3(0.05, 0.2, 0.4));
  check_point(checker, rotation_from_euler_degrees(-20, 5, 0),
              make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.1), 0.25), 2e-3, 16);
}

TEST(RenderReference, SunSplitFromTheRestOfTheMap) {
  // A 0.5 degree sun holding most of the light, on a 256x128 map where detect_sun finds it: the strategies that
  // split it off (light, mis, mis-compensated with sun samples) converge to the same integral as those that do not.
  const probes::SunProbe sun(Vec3(0.3, 0.7, -0.2).normalized(), probes::radians(0.5), Vec3(3e4, 2.8e4, 2.5e4),
                             Vec3(0.4, 0.5, 0.8));
  EXPECT_GE(check_point(sun, rotation_from_euler_degrees(25, 0, 0), make_diffuse(Vec3(0.8, 0.6, 0.4)), 2e-3, 0, 256, 3),
            5);
  EXPECT_GE(check_point(sun, identity3(), make_conductor(Vec3(0.0), Vec3(1.0), 0.3), 3e-3, 0, 256, 3), 5);
  // A plastic: the product strategies draw from the mixture of its base's and its coat's tables beside the sun.
  EXPECT_GE(
      check_point(sun, rotation_from_euler_degrees(-40, 0, 0), make_plastic(Vec3(0.5, 0.4, 0.3), 0.1), 3e-3, 0, 256, 3),
      5);
  // The sun turned below the shading point's horizon: BSDF sampling alone cannot find a sun in view. A lobe between
  // kSunSampleAlpha and kWideLobeAlpha takes sun samples beside its narrow-lobe counts; a narrower one keeps the
  // whole map's table (takes_sun_samples()): the same integral for both.
  for (const double alpha : {0.15, 0.05})
    EXPECT_GE(check_point(sun, rotation_from_euler_degrees(0, 120, 0), make_conductor(Vec3(0.0), Vec3(1.0), alpha),
                          3e-3, 0, 256, 3),
              5)
        << alpha;
}

// Which materials draw the sun apart: those whose widest lobe reaches kSunSampleAlpha.
TEST(RenderSunSamples, ByWidestLobe) {
  const auto conductor = [](double alpha) { return make_conductor(Vec3(0.0), Vec3(1.0), alpha); };
  for (const auto& m : {make_diffuse(Vec3(0.5)), make_plastic(Vec3(0.5), 0.02), conductor(0.3), conductor(0.15),
                        conductor(kSunSampleAlpha)})
    EXPECT_TRUE(takes_sun_samples(*m)) << m->name() << " " << m->widest_lobe_alpha();
  for (const auto& m : {conductor(0.09), conductor(0.02), make_mirror(Vec3(0.9))})
    EXPECT_FALSE(takes_sun_samples(*m)) << m->name() << " " << m->widest_lobe_alpha();
}

// Counts the options leave unset follow the material's lobe, whatever the sun; given counts hold for every
// material.
TEST(RenderSampleCounts, ByLobeUnlessGiven) {
  const IntegratorOptions unset;
  const auto diffuse = make_diffuse(Vec3(0.5)), rough_plastic = make_plastic(Vec3(0.5), 0.3);
  const auto glossy_plastic = make_plastic(Vec3(0.5), 0.05);  // a wide base, a narrow coat
  const auto narrow = make_conductor(Vec3(0.0), Vec3(1.0), 0.05), wide = make_conductor(Vec3(0.0), Vec3(1.0), 0.3);
  for (const Material* m : {diffuse.get(), rough_plastic.get(), wide.get()}) {
    EXPECT_EQ(sample_counts(unset, *m).bsdf, 1) << m->name();
    EXPECT_EQ(sample_counts(unset, *m).light, kWideLightSamples) << m->name();
  }
  for (const Material* m : {narrow.get(), glossy_plastic.get()}) {
    EXPECT_EQ(sample_counts(unset, *m).bsdf, kNarrowBsdfSamples) << m->name();
    EXPECT_EQ(sample_counts(unset, *m).light, kNarrowLightSamples) << m->name();
  }
  IntegratorOptions given;
  given.light_samples = 5;
  EXPECT_EQ(sample_counts(given, *narrow).light, 5);
  EXPECT_EQ(sample_counts(given, *narrow).bsdf, kNarrowBsdfSamples);
  given.bsdf_samples = 0;
  EXPECT_EQ(sample_counts(given, *diffuse).bsdf, 0);
  EXPECT_EQ(sample_counts(given, *diffuse).light, 5);
  // An integrator over a map with a dominant sun gives its materials the same counts.
  const probes::SunProbe sun(Vec3(0.3, 0.7, -0.2).normalized(), probes::radians(0.5), Vec3(3e4), Vec3(0.05));
  const Environment env(sun, identity3(), 0, 256, 128);
  Scene empty;
  empty.commit();
  const Integrator integrator(empty, *env.light, unset);
  ASSERT_NE(integrator.sun_split(), nullptr);
  EXPECT_GT(integrator.sun_split()->sun().power_share, 0.5);
  EXPECT_EQ(integrator.counts(*narrow).bsdf, kNarrowBsdfSamples);
  EXPECT_EQ(integrator.counts(*narrow).light, kNarrowLightSamples);
}

// The integrator draws those counts: light sampling of a diffuse point with the counts unset (kWideLightSamples) has
// at most about 1 / kWideLightSamples of the variance of 1 light sample. And only given counts can be refused.
TEST(RenderSampleCounts, TheIntegratorDrawsThem) {
  const Environment env(probes::CheckerProbe(4, 8, Vec3(2.0, 1.0, 0.5), Vec3(0.1, 0.3, 0.6)), identity3());
  Scene empty;
  const Material& material = empty.material(empty.add_material("m", make_diffuse(Vec3(0.8, 0.6, 0.4))));
  empty.commit();
  const Frame frame = Frame::from_normal(Vec3(0.3, 1.0, -0.2).normalized());
  const Vec3 wo = Vec3(0.35, -0.2, 0.9).normalized();
  IntegratorOptions options;
  options.strategy = Strategy::Light;
  options.sun_samples = 0;
  double variance[2];
  for (int one : {0, 1}) {
    if (one) options.light_samples = 1;
    const Integrator integrator(empty, *env.light, options);
    Vec3 mean, se;
    estimate(integrator, frame, material, wo, 4096, mean, se);
    variance[one] = se.y * se.y;
  }
  EXPECT_GT(variance[0], 0.0);
  // At most about 1/M of it (less: the M samples of a point are stratified together, Sampler::point_2d).
  EXPECT_LT(variance[0] / variance[1], 1.3 / kWideLightSamples);

  options.strategy = Strategy::Mis;
  options.light_samples = 0;  // the BSDF count is unset, so at least 1
  EXPECT_NO_THROW(Integrator(empty, *env.light, options));
  options.bsdf_samples = 0;
  EXPECT_THROW(Integrator(empty, *env.light, options), Error);
}
