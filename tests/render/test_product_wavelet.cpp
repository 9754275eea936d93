// The wavelet product sampler (product_wavelet.h, haar.h): the Haar transform and the wavelet-domain product, the
// hemisphere's square, chi-square of drawn directions against the technique's pdf for every kind of material, and
// renders that agree with product-mis.
#include <envkit/maps/latlong.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/render/product_wavelet.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/sampling/haar.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include "chi2.h"
#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

std::vector<double> random_grid(int R, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(std::size_t(R) * std::size_t(R));
  for (double& x : v) x = testmaps::uniform53(rng) * (testmaps::uniform53(rng) < 0.1 ? 100.0 : 1.0);
  return v;
}

/// A lat-long importance table: a sky brighter towards +y, a bright sun, and a dark lower half with a window.
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
      if ((d ^ sun) > std::cos(0.05)) L += 2e4;
      if ((d ^ window) > std::cos(0.3)) L += 5.0;
      weights[std::size_t(y) * W + x] = float(L * grid.texel_solid_angle(x, y));
    }
  return SphericalDistribution(Kind::LatLong, std::make_shared<HierarchicalDistribution2D>(weights.data(), W, H));
}

Vec3 unit(double x, double y, double z) { return Vec3(x, y, z) / Vec3(x, y, z).length(); }

/// Local direction of (cos theta, phi) in a frame.
Vec3 local_direction(double cos_theta, double phi) {
  const double s = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
  return Vec3(s * std::cos(phi), s * std::sin(phi), cos_theta);
}

/// Chi-square of n samples of the point's product against its pdf over the cells of its square (the pdf is
/// constant on each: expected = pdf x the cell's solid angle x n); also returns the pdf's integral over the cap.
chi2::Result chi_square(const ProductWavelet::Point& p, int R, std::size_t n, std::uint64_t seed, double& integral,
                        double alpha = 0.01) {
  const double h = p.cap(), cell_solid_angle = kTwoPi * h / (R * R);
  std::vector<double> observed(std::size_t(R * R), 0.0), expected(observed.size(), 0.0);
  integral = 0.0;
  for (int y = 0; y < R; ++y)
    for (int x = 0; x < R; ++x) {
      const Vec3 d = p.frame().to_world(cap_from_square(Vec2((x + 0.5) / R, (y + 0.5) / R), h));
      const double probability = p.pdf(d) * cell_solid_angle;
      integral += probability;
      expected[std::size_t(y * R + x)] = probability * double(n);
    }
  std::mt19937_64 rng(seed);
  for (std::size_t k = 0; k < n; ++k) {
    const DirectionSample d = p.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    EXPECT_GT(d.pdf, 0.0);
    const Vec2 uv = square_from_cap(p.frame().to_local(d.direction), h);
    observed[std::size_t(std::min(int(uv.y * R), R - 1) * R + std::min(int(uv.x * R), R - 1))] += 1.0;
  }
  return chi2::test(observed, expected, alpha);
}

}  // namespace

TEST(Haar, RoundTripsAndKeepsEnergy) {
  for (int R : {2, 8, 32}) {
    const std::vector<double> v = random_grid(R, 7 + R);
    std::vector<double> c = v;
    haar::forward(c, R);
    double e_v = 0, e_c = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      e_v += v[i] * v[i];
      e_c += c[i] * c[i];
    }
    EXPECT_NEAR(e_c, e_v, 1e-9 * e_v) << R;  // orthonormal: Parseval
    double sum = 0;
    for (double x : v) sum += x;
    EXPECT_NEAR(c[0], sum / R, 1e-9 * sum) << R;  // the root's scaling coefficient
    haar::inverse(c, R);
    for (std::size_t i = 0; i < v.size(); ++i) ASSERT_NEAR(c[i], v[i], 1e-9 * (1 + std::abs(v[i]))) << R << " " << i;
  }
  std::vector<double> bad(12);
  EXPECT_THROW(haar::forward(bad, 3), Error);
}

TEST(Haar, CompressionKeepsTheLargestCoefficients) {
  const int R = 16;
  std::vector<double> c = random_grid(R, 3);
  haar::forward(c, R);
  const double root = c[0];
  double smallest_kept = 1e300;
  std::vector<double> kept = c;
  EXPECT_EQ(haar::keep_largest(kept, R, 20), 21u);
  EXPECT_EQ(kept[0], root);
  double largest_dropped = 0;
  for (std::size_t i = 1; i < c.size(); ++i)
    if (kept[i] != 0.0)
      smallest_kept = std::min(smallest_kept, std::abs(c[i]));
    else
      largest_dropped = std::max(largest_dropped, std::abs(c[i]));
  EXPECT_GE(smallest_kept, largest_dropped);
}

TEST(Haar, WaveletProductSumsEqualThePointwiseProductSums) {
  const int R = 32;
  const std::vector<double> a = random_grid(R, 11), b = random_grid(R, 12);
  std::vector<double> ca = a, cb = b;
  haar::forward(ca, R);
  haar::forward(cb, R);
  const std::vector<std::vector<double>> sums = haar::product_sums(ca, cb, R);
  ASSERT_EQ(sums.size(), 6u);
  for (int k = 0; k <= 5; ++k) {
    const int m = R >> k, side = 1 << k;
    ASSERT_EQ(sums[std::size_t(k)].size(), std::size_t(m * m));
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        double direct = 0;
        for (int y = j * side; y < (j + 1) * side; ++y)
          for (int x = i * side; x < (i + 1) * side; ++x)
            direct += a[std::size_t(y * R + x)] * b[std::size_t(y * R + x)];
        ASSERT_NEAR(sums[std::size_t(k)][std::size_t(j * m + i)], direct, 1e-9 * direct) << k << " " << i << "," << j;
      }
  }
}

TEST(ProductWavelet, TheSquareCoversTheCapByEqualAreas) {
  for (double h : {1.0, 1.2}) {
    std::mt19937_64 rng(5);
    // Uniform points of the square are uniform over the cap: equal counts in bins of equal (z, phi) extent.
    const int rows = 8, cols = 16;
    const std::size_t n = 200000;
    std::vector<double> observed(std::size_t(rows * cols), 0.0), expected(observed.size(), double(n) / (rows * cols));
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
      const Vec3 d = cap_from_square(u, h);
      ASSERT_NEAR(d.length(), 1.0, 1e-12);
      ASSERT_GE(d.z, 1.0 - h - 1e-12);
      const Vec2 back = square_from_cap(d, h);
      ASSERT_NEAR(back.x, u.x, 1e-9) << u.x << "," << u.y;
      ASSERT_NEAR(back.y, u.y, 1e-9) << u.x << "," << u.y;
      double phi = std::atan2(d.y, d.x);
      if (phi < 0.0) phi += kTwoPi;
      const int r = std::clamp(int((1.0 - d.z) / h * rows), 0, rows - 1);
      const int c = std::clamp(int(phi / kTwoPi * cols), 0, cols - 1);
      observed[std::size_t(r * cols + c)] += 1.0;
    }
    const chi2::Result r = chi2::test(observed, expected, 0.01);
    EXPECT_TRUE(r.passed) << "h " << h << ": " << r.message;
  }
}

TEST(ProductWavelet, SamplesFollowThePdfForEveryMaterial) {
  const SphericalDistribution env = test_environment();
  std::vector<std::pair<std::string, std::unique_ptr<Material>>> materials;
  materials.emplace_back("diffuse", make_diffuse(Vec3(0.8, 0.5, 0.3)));
  materials.emplace_back("conductor 0.1", make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.1));
  materials.emplace_back("conductor 0.3", make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.3));
  materials.emplace_back("plastic", make_plastic(Vec3(0.1, 0.4, 0.7), 0.15));
  std::vector<const Material*> list;
  for (const auto& m : materials) list.push_back(m.second.get());
  const ProductWavelet wavelet(env, list, WaveletOptions{});
  const Vec3 normals[] = {unit(0, 1, 0), unit(0.3, 0.8, 0.2), unit(-0.7, 0.1, 0.6)};
  const Vec3 wos[] = {unit(0.1, 0.2, 1.0), unit(0.9, -0.1, 0.3)};  // local: near-normal and grazing
  int tests = 0;
  // Every case at p > 0.01 as a family (Sidak): one failure among 24 cases at 0.01 each happens one run in five.
  const double alpha = chi2::sidak_alpha(0.01, 4 * 3 * 2);
  for (const auto& m : materials)
    for (const Vec3& n : normals)
      for (const Vec3& wo_local : wos) {
        const Frame f = Frame::from_normal(n);
        const ProductWavelet::Point p = wavelet.at(n, f.to_world(wo_local), *m.second);
        double integral = 0;
        const chi2::Result r =
            chi_square(p, 32, 300000, testmaps::seed_of(m.first, std::uint64_t(tests)), integral, alpha);
        std::printf("%s %d: %s\n", m.first.c_str(), tests, r.message.c_str());
        EXPECT_TRUE(r.passed) << m.first << " normal " << tests << ": " << r.message;
        EXPECT_NEAR(integral, 1.0, 1e-5) << m.first;
        ++tests;
      }
}

TEST(ProductWavelet, PdfIsPositiveOverTheWholeHemisphereAndMatchesSamples) {
  const SphericalDistribution env = test_environment();
  const auto glossy = make_conductor(Vec3(0.2, 0.9, 1.1), Vec3(3.9, 2.4, 2.2), 0.05);
  WaveletOptions compressed;
  compressed.kept_coefficients = 16;  // lossy: only the shape changes, never the support
  const ProductWavelet wavelet(env, {glossy.get()}, compressed);
  const Vec3 n = unit(0.2, -0.3, 0.9);  // faces away from the sun
  const Frame f = Frame::from_normal(n);
  const ProductWavelet::Point p = wavelet.at(n, f.to_world(unit(0.5, 0.1, 0.4)), *glossy);
  std::mt19937_64 rng(9);
  for (int k = 0; k < 20000; ++k) {
    // Every direction of the point's hemisphere, also a hair above its horizon.
    const double ct = k < 100 ? 1e-7 : testmaps::uniform53(rng), phi = kTwoPi * testmaps::uniform53(rng);
    ASSERT_GT(p.pdf(f.to_world(local_direction(ct, phi))), 0.0) << ct << " " << phi;
    const DirectionSample s = p.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    ASSERT_GT(s.pdf, 0.0);
    ASSERT_NEAR(p.pdf(s.direction), s.pdf, 1e-6 * s.pdf);
  }
  EXPECT_EQ(p.pdf(-n), 0.0);
  // The density per steradian integrates to 1, independently of the square: uniform directions over the sphere.
  double sum = 0, sum2 = 0;
  const int m = 400000;
  for (int k = 0; k < m; ++k) {
    const double z = 2.0 * testmaps::uniform53(rng) - 1.0, phi = kTwoPi * testmaps::uniform53(rng);
    const double v = kFourPi * p.pdf(local_direction(z, phi));
    sum += v;
    sum2 += v * v;
  }
  const double mean = sum / m, se = std::sqrt((sum2 / m - mean * mean) / m);
  EXPECT_NEAR(mean, 1.0, 4.0 * se + 1e-6) << "se " << se;
  double integral = 0;
  const chi2::Result r = chi_square(p, 32, 1000000, 99, integral);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_NEAR(integral, 1.0, 1e-5);
}

namespace {

LoadedScene default_scene_with(const std::string& probe_json, int width, int height) {
  std::string text = default_scene_json();
  const std::string from = R"("probe": "default", "size": [1024, 512])";
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos) text.replace(at, from.size(), probe_json);
  SceneLoadOptions options;
  options.width = width;
  options.height = height;
  return load_scene_text(text, "wavelet-default.json", options);
}

}  // namespace

TEST(ProductWavelet, RenderAgreesWithProductMis) {
  const LoadedScene scene = default_scene_with(R"("probe": "default", "size": [256, 128])", 48, 24);
  RenderOptions ro;
  ro.spp = 64;
  std::vector<std::vector<double>> means(3), vars(3);
  const Strategy strategies[] = {Strategy::ProductMis, Strategy::ProductWaveletMis, Strategy::ProductWavelet};
  for (int s = 0; s < 3; ++s) {
    IntegratorOptions o;
    o.strategy = strategies[s];
    const Integrator integrator(*scene.scene, *scene.light, o);
    const Film film = render_image(scene.camera, integrator, ro);
    EXPECT_EQ(integrator.nonfinite_count(), 0u);
    envkit::test::region_stats(film, 4, 2, means[std::size_t(s)], vars[std::size_t(s)]);
  }
  for (std::size_t r = 0; r < means[0].size(); ++r)
    for (int s = 1; s < 3; ++s) {
      const double z = (means[std::size_t(s)][r] - means[0][r]) / std::sqrt(vars[std::size_t(s)][r] + vars[0][r]);
      std::printf("  region %zu %-20s %.5f vs product-mis %.5f (z %+.2f, rel.se %.1e vs %.1e)\n", r,
                  strategy_name(strategies[s]), means[std::size_t(s)][r], means[0][r], z,
                  std::sqrt(vars[std::size_t(s)][r]) / means[0][r], std::sqrt(vars[0][r]) / means[0][r]);
      EXPECT_LT(std::abs(z), 4.0) << strategy_name(strategies[s]) << " region " << r;
    }
}

TEST(ProductWavelet, NoNonFiniteValuesUnderAMillionSun) {
  const LoadedScene scene = default_scene_with(
      R"("probe": "sun", "radiance": 1e6, "sky": 1e-3, "radius_deg": 0.1, "elevation_deg": 40, "azimuth_deg": 20, "size": [256, 128])",
      32, 16);
  for (Strategy s : {Strategy::ProductWavelet, Strategy::ProductWaveletMis})
    for (int depth : {3}) {  // (depth 3 includes the direct light of depth 1)
      IntegratorOptions o;
      o.strategy = s;
      o.max_depth = depth;
      const Integrator integrator(*scene.scene, *scene.light, o);
      RenderOptions ro;
      ro.spp = 4;
      const Film film = render_image(scene.camera, integrator, ro);
      EXPECT_EQ(integrator.nonfinite_count(), 0u) << strategy_name(s);
      EXPECT_GT(envkit::test::expect_finite_film(film, strategy_name(s)), 0.0) << strategy_name(s);
    }
}

TEST(ProductWavelet, BadOptionsAreErrors) {
  const SphericalDistribution env = test_environment(64, 32);
  for (int R : {0, 3, 512}) {
    WaveletOptions o;
    o.resolution = R;
    EXPECT_THROW(ProductWavelet(env, {}, o), Error) << R;
  }
  WaveletOptions o;
  o.normal_bins = 0;
  EXPECT_THROW(ProductWavelet(env, {}, o), Error);
  EXPECT_EQ(parse_strategy("product-wavelet"), Strategy::ProductWavelet);
  EXPECT_EQ(parse_strategy("product-wavelet-mis"), Strategy::ProductWaveletMis);
}

TEST(ProductWavelet, DeltaAndUnknownMaterialsHaveAConstantBsdfFactor) {
  const SphericalDistribution env = test_environment(64, 32);
  const auto mirror = make_mirror(Vec3(0.9, 0.9, 0.9));
  const auto diffuse = make_diffuse(Vec3(0.5, 0.5, 0.5));
  const auto other = make_diffuse(Vec3(0.2, 0.2, 0.2));
  WaveletOptions o;
  o.wo_bins = 4;
  const ProductWavelet wavelet(env, {mirror.get(), diffuse.get()}, o);
  EXPECT_EQ(wavelet.brdf(*mirror, Vec3(0, 0, 1)), nullptr);  // pure delta: followed by BSDF sampling instead
  EXPECT_EQ(wavelet.brdf(*other, Vec3(0, 0, 1)), nullptr);   // not among the scene's: the lighting alone
  ASSERT_NE(wavelet.brdf(*diffuse, Vec3(0, 0, 1)), nullptr);
  const Vec3 n = unit(0.1, 0.9, 0.2);
  for (const Material* m : {static_cast<const Material*>(mirror.get()), static_cast<const Material*>(other.get())}) {
    const ProductWavelet::Point p = wavelet.at(n, n, *m);
    double integral = 0;
    const chi2::Result r = chi_square(p, 32, 100000, 5, integral);
    EXPECT_TRUE(r.passed) << r.message;
    EXPECT_NEAR(integral, 1.0, 1e-5);
  }
  // Diffuse x cos: the factor of a cell near the normal is larger than one near the cap's rim.
  const float* f = wavelet.brdf(*diffuse, Vec3(0, 0, 1));
  EXPECT_GT(f[16 * 32 + 16], 10.0f * f[0]);
}
