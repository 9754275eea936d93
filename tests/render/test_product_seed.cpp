// The seed's two basis product samplers (basis_hierarchy.h, product_steerable.h, product_sh.h): the quadtree warping
// of clamped coefficient masses, the BSDF lobe fit, chi-square of drawn directions against the returned pdf for
// every kind of material (measured included), the pdf's support and integral, renders that agree with product-mis,
// the furnace, a 1e6 sun, and pixels independent of crop, tiles and threads.
#include <envkit/core/sh_basis.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/basis_hierarchy.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/render/product_sh.h>
#include <envkit/render/product_steerable.h>
#include <envkit/render/product_wavelet.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>

#include "../../renderer/src/merl.h"  // private: the format's cells, to write a measured file
#include "chi2.h"
#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

namespace fs = std::filesystem;

/// The SH order the tests use (the samplers' default is larger; the tests' cost grows with K^2).
constexpr int kTestOrder = 6;

BasisProductOptions test_options() {
  BasisProductOptions o;
  o.order = kTestOrder;
  return o;
}

/// A lat-long importance table: a sky brighter towards +y, a broad bright patch and a window below the horizon.
/// Smooth enough that a fine midpoint quadrature of its density over a bin is exact to well under the chi-square's
/// resolution.
SphericalDistribution test_environment(int W = 256, int H = 128) {
  std::vector<float> weights(std::size_t(W) * std::size_t(H));
  const Vec3 sun = Vec3(0.4, 0.7, 0.3) / Vec3(0.4, 0.7, 0.3).length();
  const Vec3 window = Vec3(-0.6, -0.2, 0.5) / Vec3(-0.6, -0.2, 0.5).length();
  auto probe = std::make_shared<HierarchicalDistribution2D>(weights.data(), W, H);  // for the grid's geometry
  const SphericalDistribution grid(Kind::LatLong, probe);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Vec3 d = grid.direction_in_texel(x, y, 0.5, 0.5);
      double L = d.y > 0.0 ? 0.5 + d.y : 0.02;
      L += 50.0 * std::exp(-(1.0 - (d ^ sun)) * 60.0);
      if ((d ^ window) > std::cos(0.3)) L += 5.0;
      weights[std::size_t(y) * W + x] = float(L * grid.texel_solid_angle(x, y));
    }
  return SphericalDistribution(Kind::LatLong, std::make_shared<HierarchicalDistribution2D>(weights.data(), W, H));
}

Vec3 unit(double x, double y, double z) { return Vec3(x, y, z) / Vec3(x, y, z).length(); }

/// Chi-square of n samples against the pdf over B x B bins of the sphere's square; a bin's expected count is the
/// pdf integrated by a 16 x 16 midpoint rule (exact for the quadtree's part, whose cells the bins align with).
/// Also returns that integral over the sphere.
template <class Point>
chi2::Result chi_square(const Point& p, int B, std::size_t n, std::uint64_t seed, double& integral, double alpha) {
  const int S = 16;
  const double w = kFourPi / (double(B) * B * S * S);
  std::vector<double> observed(std::size_t(B * B), 0.0), expected(observed.size(), 0.0);
  integral = 0.0;
  for (int y = 0; y < B; ++y)
    for (int x = 0; x < B; ++x) {
      double mass = 0.0;
      for (int sy = 0; sy < S; ++sy)
        for (int sx = 0; sx < S; ++sx)
          mass += w * p.pdf(cap_from_square(Vec2((x + (sx + 0.5) / S) / B, (y + (sy + 0.5) / S) / B), kWholeSphere));
      integral += mass;
      expected[std::size_t(y * B + x)] = mass * double(n);
    }
  std::mt19937_64 rng(seed);
  for (std::size_t k = 0; k < n; ++k) {
    const DirectionSample d = p.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    EXPECT_GT(d.pdf, 0.0);
    const Vec2 uv = square_from_cap(d.direction, kWholeSphere);
    observed[std::size_t(std::min(int(uv.y * B), B - 1) * B + std::min(int(uv.x * B), B - 1))] += 1.0;
  }
  return chi2::test(observed, expected, alpha);
}

/// This process's directory for the MERL file (35 MB), removed when the tests end.
fs::path work_dir() { return fs::temp_directory_path() / ("envkit_seed_" + std::to_string(::getpid())); }

class RemoveWorkDir final : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(work_dir(), ec);
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveWorkDir = ::testing::AddGlobalTestEnvironment(new RemoveWorkDir);

/// A measured material: a MERL file written from a white GGX conductor of alpha 0.3 (F = 1).
std::unique_ptr<Material> measured_ggx() {
  const auto ggx = make_conductor(Vec3(0.0), Vec3(1.0), 0.3);
  fs::create_directories(work_dir());
  const fs::path file = work_dir() / "ggx.binary";
  if (!fs::exists(file)) {
    std::vector<double> v(3 * merl::kCells);
    for (int th = 0; th < merl::kThetaHalfCells; ++th)
      for (int td = 0; td < merl::kThetaDiffCells; ++td)
        for (int pd = 0; pd < merl::kPhiDiffCells; ++pd) {
          merl::HalfDiff hd{merl::theta_half_of_cell(th), merl::theta_diff_of_cell(td), merl::phi_diff_of_cell(pd)};
          Vec3 wo, wi;
          merl::directions(hd, wo, wi);
          const bool missing = !(wo.z > 0.0 && wi.z > 0.0);
          const Vec3 f = missing ? Vec3(0.0) : ggx->eval(wo, wi) / wi.z;
          const std::size_t i = merl::cell_index(th, td, pd);
          for (int c = 0; c < 3; ++c) v[std::size_t(c) * merl::kCells + i] = missing ? -1.0 : f[c] / merl::kScale[c];
        }
    const std::int32_t dims[3] = {merl::kThetaHalfCells, merl::kThetaDiffCells, merl::kPhiDiffCells};
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(dims), sizeof dims);
    out.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(double)));
  }
  return make_measured(file.string());
}

struct NamedMaterial {
  std::string name;
  std::unique_ptr<Material> material;
};

std::vector<NamedMaterial> every_kind() {
  std::vector<NamedMaterial> m;
  m.push_back({"diffuse", make_diffuse(Vec3(0.8, 0.5, 0.3))});
  m.push_back({"conductor 0.05", make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.05)});
  m.push_back({"conductor 0.3", make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.3)});
  m.push_back({"plastic", make_plastic(Vec3(0.1, 0.4, 0.7), 0.15)});
  m.push_back({"measured", measured_ggx()});
  return m;
}

std::vector<const Material*> pointers(const std::vector<NamedMaterial>& m) {
  std::vector<const Material*> list;
  for (const auto& x : m) list.push_back(x.material.get());
  return list;
}

}  // namespace

TEST(BasisHierarchy, WarpingDrawsItsPdfWithNegativeMassesClamped) {
  const int R = 16, K = 3;
  std::mt19937_64 rng(3);
  std::vector<double> finest(std::size_t(R * R * K));
  for (std::size_t c = 0; c < std::size_t(R * R); ++c) {
    finest[c * K + 0] = 1.0 + testmaps::uniform53(rng);
    finest[c * K + 1] = testmaps::uniform53(rng) - 0.5;
    finest[c * K + 2] = (c % 7 == 0) ? 20.0 : 0.0;
  }
  const BasisHierarchy h(R, K, finest);
  const double c[K] = {0.3, 2.0, 0.05};  // negative masses where the second function is below -0.15
  ASSERT_TRUE(h.can_sample(c));
  struct Adapter {
    const BasisHierarchy& h;
    const double* c;
    DirectionSample sample(Vec2 u) const { return h.sample(c, u); }
    double pdf(const Vec3& d) const { return h.pdf(c, d); }
  } p{h, c};
  double integral = 0.0;
  const chi2::Result r = chi_square(p, R, 400000, 17, integral, 0.01);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(integral, 1.0, 1e-9);
  // Every drawn direction's pdf is the one sample() returned.
  for (int k = 0; k < 2000; ++k) {
    const DirectionSample s = h.sample(c, Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    ASSERT_NEAR(h.pdf(c, s.direction), s.pdf, 1e-9 * s.pdf);
  }
  // A cell whose mass is negative is never drawn: its pdf is 0.
  int zero = 0;
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const float* v = h.node(4, x, y);
      const double m = c[0] * v[0] + c[1] * v[1] + c[2] * v[2];
      const double p_cell = h.pdf(c, cap_from_square(Vec2((x + 0.5) / R, (y + 0.5) / R), kWholeSphere));
      if (m < 0.0) {
        EXPECT_EQ(p_cell, 0.0);
        ++zero;
      }
    }
  EXPECT_GT(zero, 0);  // the test covers the clamp
  EXPECT_THROW(BasisHierarchy(12, 1, std::vector<double>(144)), Error);
}

TEST(BsdfLobeFit, LobesPointWhereTheBsdfReflects) {
  const auto diffuse = make_diffuse(Vec3(0.8));
  const auto glossy = make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.1);
  const BsdfLobeFit fit({diffuse.get(), glossy.get()}, kTestOrder, 16);
  const int K = sh_count(kTestOrder);
  std::vector<double> c(static_cast<std::size_t>(K)), y(static_cast<std::size_t>(K));
  const auto value = [&](const Vec3& d) {
    sh_basis(kTestOrder, d, y.data());
    double s = 0.0;
    for (int i = 0; i < K; ++i) s += c[std::size_t(i)] * y[std::size_t(i)];
    return s;
  };
  const Vec3 n = unit(0.2, 0.9, -0.1), wo = unit(0.9, 0.5, 0.2);
  const Vec3 r = n * (2.0 * (n ^ wo)) - wo;
  fit.coefficients(*diffuse, n, wo, c.data());
  // Diffuse x cos: albedo / pi at the normal, 0 below.
  EXPECT_NEAR(value(n), 0.8 / kPi, 0.1 * 0.8 / kPi);
  EXPECT_LT(std::abs(value(-n)), 0.1 * value(n));
  fit.coefficients(*glossy, n, wo, c.data());
  EXPECT_GT(value(r), 5.0 * value(n));
  EXPECT_GT(value(r), 5.0 * std::abs(value(-r)));
}

TEST(BsdfLobeFit, AMeasuredBsdfFitsAsItsAnalyticTwin) {
  // The MERL file holds a white GGX conductor of alpha 0.3 (F = 1): through eval(), pdf() and sample() alone its
  // fit is the analytic material's, up to the table's resolution and the fit's sampling.
  const auto measured = measured_ggx();
  const auto analytic = make_conductor(Vec3(0.0), Vec3(1.0), 0.3);
  const BsdfLobeFit fit({measured.get(), analytic.get()}, kTestOrder, 8);
  for (double cos_o : {0.95, 0.6, 0.3}) {
    std::vector<double> am, bm, aa, ba;
    ASSERT_TRUE(fit.lobes(*measured, cos_o, am, bm));
    ASSERT_TRUE(fit.lobes(*analytic, cos_o, aa, ba));
    double diff = 0.0, norm = 0.0;
    for (std::size_t l = 0; l < am.size(); ++l) {
      diff += (am[l] - aa[l]) * (am[l] - aa[l]) + (bm[l] - ba[l]) * (bm[l] - ba[l]);
      norm += aa[l] * aa[l] + ba[l] * ba[l];
    }
    EXPECT_LT(std::sqrt(diff / norm), 0.1) << "cos theta_o " << cos_o;
  }
}

TEST(ProductSeed, SamplesFollowThePdfForEveryMaterial) {
  const SphericalDistribution env = test_environment();
  const std::vector<NamedMaterial> materials = every_kind();
  const ProductSteerable steerable(env, pointers(materials), test_options());
  const ProductSh sh(env, pointers(materials), test_options());
  const Vec3 n = unit(0.3, 0.8, 0.2);
  const Frame f = Frame::from_normal(n);
  const Vec3 wo = f.to_world(unit(0.6, 0.2, 0.7));
  const double alpha = chi2::sidak_alpha(0.01, 2 * int(materials.size()));
  int tests = 0;
  for (const NamedMaterial& m : materials)
    for (int which = 0; which < 2; ++which) {
      const BasisProductPoint p = which == 0 ? steerable.at(n, wo, *m.material) : sh.at(n, wo, *m.material);
      const char* name = which == 0 ? "steerable" : "sh";
      double integral = 0.0;
      const chi2::Result r =
          chi_square(p, 32, 1000000, testmaps::seed_of(m.name + name, std::uint64_t(tests++)), integral, alpha);
      std::printf("%s %s: %s (integral %.6f, defensive %.2f)\n", name, m.name.c_str(), r.message.c_str(), integral,
                  p.defensive());
      EXPECT_TRUE(r.passed) << name << " " << m.name << ": " << r.message;
      EXPECT_NEAR(integral, 1.0, 2e-3) << name << " " << m.name;
      EXPECT_LT(p.defensive(), 1.0) << name << " " << m.name << ": the product itself is sampled";
    }
}

TEST(ProductSeed, PdfIsPositiveWhereverTheIntegrandIsAndMatchesSamples) {
  const SphericalDistribution env = test_environment();
  const auto glossy = make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.05);
  const ProductSteerable steerable(env, {glossy.get()}, test_options());
  const ProductSh sh(env, {glossy.get()}, test_options());
  const Vec3 n = unit(0.2, -0.3, 0.9);  // faces away from the bright patch
  const Frame f = Frame::from_normal(n);
  const Vec3 wo = f.to_world(unit(0.5, 0.1, 0.4));
  for (const BasisProductPoint& p : {steerable.at(n, wo, *glossy), sh.at(n, wo, *glossy)}) {
    std::mt19937_64 rng(9);
    for (int k = 0; k < 20000; ++k) {
      const double z = 2.0 * testmaps::uniform53(rng) - 1.0, phi = kTwoPi * testmaps::uniform53(rng);
      const double s = std::sqrt(1.0 - z * z);
      const Vec3 d(s * std::cos(phi), s * std::sin(phi), z);
      if (env.pdf(d) > 0.0) {
        ASSERT_GT(p.pdf(d), 0.0);  // the environment is bright everywhere here
      }
      const DirectionSample x = p.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
      ASSERT_GT(x.pdf, 0.0);
      ASSERT_NEAR(p.pdf(x.direction), x.pdf, 1e-9 * x.pdf);
    }
  }
}

TEST(ProductSeed, UnknownAndDeltaMaterialsSampleTheLightingAlone) {
  const SphericalDistribution env = test_environment(64, 32);
  const auto mirror = make_mirror(Vec3(0.9));
  const auto other = make_diffuse(Vec3(0.2));
  const ProductSteerable steerable(env, {mirror.get()}, test_options());
  const Vec3 n = unit(0.1, 0.9, 0.2);
  for (const Material* m : {static_cast<const Material*>(mirror.get()), static_cast<const Material*>(other.get())}) {
    const BasisProductPoint p = steerable.at(n, n, *m);
    for (std::size_t i = 1; i < p.coefficients().size(); ++i) EXPECT_EQ(p.coefficients()[i], 0.0);
    double integral = 0;
    const chi2::Result r = chi_square(p, 16, 100000, 5, integral, 0.01);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(integral, 1.0, 2e-3);
  }
}

TEST(ProductSeed, BadOptionsAreErrors) {
  const SphericalDistribution env = test_environment(64, 32);
  const auto bad = [](auto change) {
    BasisProductOptions o = test_options();
    change(o);
    return o;
  };
  for (const BasisProductOptions& o :
       {bad([](BasisProductOptions& x) { x.order = 0; }), bad([](BasisProductOptions& x) { x.order = 17; }),
        bad([](BasisProductOptions& x) { x.resolution = 48; }),
        bad([](BasisProductOptions& x) { x.resolution = 1024; }), bad([](BasisProductOptions& x) { x.wo_bins = 1; }),
        bad([](BasisProductOptions& x) { x.defensive = 0.0; }),
        bad([](BasisProductOptions& x) { x.defensive = std::nan(""); })}) {
    EXPECT_THROW(ProductSteerable(env, {}, o), Error);
    EXPECT_THROW(ProductSh(env, {}, o), Error);
  }
  for (const char* name : {"product-steerable", "product-steerable-mis", "product-sh", "product-sh-mis"})
    EXPECT_STREQ(strategy_name(parse_strategy(name)), name);
  IntegratorOptions o;
  o.strategy = Strategy::ProductSh;
  o.light_method = SamplingMethod::Cdf;
  EXPECT_THROW(validate(o), IntegratorOptionsError);
  o.light_method = SamplingMethod::Hierarchical;
  o.light_samples = 0;
  EXPECT_THROW(validate(o), IntegratorOptionsError);
  o.strategy = Strategy::ProductSteerableMis;
  EXPECT_NO_THROW(validate(o));
}

namespace {

LoadedScene scene_with(const std::string& probe_json, int width, int height) {
  std::string text = default_scene_json();
  const std::string from = R"("probe": "default", "size": [1024, 512])";
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos) text.replace(at, from.size(), probe_json);
  SceneLoadOptions options;
  options.width = width;
  options.height = height;
  return load_scene_text(text, "seed-default.json", options);
}

IntegratorOptions seed_options(Strategy s) {
  IntegratorOptions o;
  o.strategy = s;
  o.steerable = test_options();
  o.sh = test_options();
  return o;
}

const Strategy kSeedStrategies[] = {Strategy::ProductSteerable, Strategy::ProductSteerableMis, Strategy::ProductSh,
                                    Strategy::ProductShMis};

}  // namespace

TEST(ProductSeed, RenderAgreesWithProductMis) {
  const LoadedScene scene = scene_with(R"("probe": "default", "size": [256, 128])", 48, 24);
  RenderOptions ro;
  ro.spp = 64;
  std::vector<std::vector<double>> means(5), vars(5);
  std::vector<Strategy> strategies = {Strategy::ProductMis};
  strategies.insert(strategies.end(), std::begin(kSeedStrategies), std::end(kSeedStrategies));
  for (std::size_t s = 0; s < strategies.size(); ++s) {
    IntegratorOptions o = seed_options(strategies[s]);
    if (s == 0) o.strategy = Strategy::ProductMis;
    const Integrator integrator(*scene.scene, *scene.light, o);
    RenderOptions r = ro;
    if (s == 0) r.spp = 256;  // the reference
    const Film film = render_image(scene.camera, integrator, r);
    EXPECT_EQ(integrator.nonfinite_count(), 0u);
    envkit::test::region_stats(film, 4, 2, means[s], vars[s]);
  }
  for (std::size_t r = 0; r < means[0].size(); ++r)
    for (std::size_t s = 1; s < strategies.size(); ++s) {
      const double z = (means[s][r] - means[0][r]) / std::sqrt(vars[s][r] + vars[0][r]);
      std::printf("  region %zu %-22s %.5f vs product-mis %.5f (z %+.2f, rel.se %.1e vs %.1e)\n", r,
                  strategy_name(strategies[s]), means[s][r], means[0][r], z, std::sqrt(vars[s][r]) / means[0][r],
                  std::sqrt(vars[0][r]) / means[0][r]);
      EXPECT_LT(std::abs(z), 4.0) << strategy_name(strategies[s]) << " region " << r;
    }
}

TEST(ProductSeed, WhiteFurnaceRendersOne) {
  LatLongMap grid(64, 32);
  LoadOptions load;
  load.kind = Kind::LatLong;
  const EnvMap map = make_envmap(probes::rasterize(probes::ConstantProbe(Vec3(1.0)), grid), "constant", load);
  const auto tables = std::make_shared<EnvTables>(EnvTables::bake(map, BakeOptions{}));
  const EnvironmentLight light(map, tables);
  Scene scene;
  scene.add_sphere(Vec3(0, 0, 0), 1.0, scene.add_material("white", make_diffuse(Vec3(1.0))));
  scene.commit();
  const Camera camera{Vec3(0, 0, -4), Vec3(0, 0, 0), Vec3(0, 1, 0), 20.0, 8, 8};
  for (Strategy s : kSeedStrategies) {
    const Integrator integrator(scene, light, seed_options(s));
    RenderOptions ro;
    ro.spp = 16;
    const Film film = render_image(camera, integrator, ro);
    double sum = 0.0, var = 0.0;
    for (int y = 0; y < film.height(); ++y)
      for (int x = 0; x < film.width(); ++x) {
        sum += film.mean(x, y).y;
        var += film.variance(x, y).y;
      }
    const double n = double(film.width()) * film.height();
    EXPECT_NEAR(sum / n, 1.0, 4.0 * std::sqrt(var) / n + 1e-6) << strategy_name(s);
  }
}

TEST(ProductSeed, NoNonFiniteValuesUnderAMillionSun) {
  const LoadedScene scene = scene_with(
      R"("probe": "sun", "radiance": 1e6, "sky": 1e-3, "radius_deg": 0.1, "elevation_deg": 40, "azimuth_deg": 20, "size": [256, 128])",
      32, 16);
  for (Strategy s : kSeedStrategies) {
    IntegratorOptions o = seed_options(s);
    o.max_depth = 3;
    const Integrator integrator(*scene.scene, *scene.light, o);
    RenderOptions ro;
    ro.spp = 4;
    const Film film = render_image(scene.camera, integrator, ro);
    EXPECT_EQ(integrator.nonfinite_count(), 0u) << strategy_name(s);
    EXPECT_GT(envkit::test::expect_finite_film(film, strategy_name(s)), 0.0) << strategy_name(s);
  }
}

TEST(ProductSeed, CropTilesAndThreadsDoNotChangePixels) {
  const LoadedScene scene = scene_with(R"("probe": "overcast", "size": [64, 32])", 24, 12);
  for (Strategy s : {Strategy::ProductSteerableMis, Strategy::ProductSh}) {
    SCOPED_TRACE(strategy_name(s));
    RenderOptions ro;
    ro.spp = 3;
    ro.seed = 42;
    envkit::test::expect_crop_matches(scene, seed_options(s), ro, Crop{5, 3, 17, 10}, 4);
  }
}
