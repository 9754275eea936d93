// BSDF x environment product sampling (renderer/include/envkit/render/product_sampling.h): pdf(sample) == sample
// pdf, chi-square of the samples against the pdf on sub-texel cells of the sphere, normalisation, unbiasedness of
// f_cos L / pdf against a quadrature, lower variance than environment sampling for a glossy lobe, no NaN under a
// 1e6 sun, invalid inputs.
#include <envkit/distribution_cdf.h>
#include <envkit/distribution_pyramid.h>
#include <envkit/env_sampling.h>
#include <envkit/error.h>
#include <envkit/latlong.h>
#include <envkit/octahedral.h>
#include <envkit/render/frame.h>
#include <envkit/render/material.h>
#include <envkit/render/product_sampling.h>

#include <gtest/gtest.h>

#include <chi2.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace envkit::render {
namespace {

using testmaps::uniform53;

/// A lat-long environment: scalar radiance per texel (the importance) and its hierarchical distribution.
struct TestEnv {
  int width = 0, height = 0;
  std::vector<float> radiance;  // per texel, per steradian
  std::shared_ptr<SphericalDistribution> dist;
  double L(int x, int y) const { return radiance[std::size_t(y) * std::size_t(width) + std::size_t(x)]; }
};

Vec3 texel_centre(int x, int y, int W, int H) { return LatLongMap::direction_from_uv((x + 0.5) / W, (y + 0.5) / H); }

/// Sky gradient (brighter towards +Y) plus a sun of the given radiance on every texel whose centre lies within
/// sun_radius_deg of sun_dir (at least the texel containing it).
TestEnv make_env(int W, int H, double sun_radiance, const Vec3& sun_dir, double sun_radius_deg) {
  TestEnv env;
  env.width = W;
  env.height = H;
  env.radiance.assign(std::size_t(W) * std::size_t(H), 0.0f);
  const LatLongMap map(W, H);
  std::vector<float> weights(env.radiance.size());
  const Vec3 sun = sun_dir.normalized();
  const Vec2 sun_uv = LatLongMap::uv_from_direction(sun);
  const int sx = std::min(int(sun_uv.x * W), W - 1), sy = std::min(int(sun_uv.y * H), H - 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Vec3 d = texel_centre(x, y, W, H);
      double L = 0.05 + 0.5 * std::max(0.0, d.y) + 0.1 * (0.5 + 0.5 * d.x);
      if ((x == sx && y == sy) || angle_between(d, sun) < sun_radius_deg * kPi / 180.0) L += sun_radiance;
      const std::size_t k = std::size_t(y) * std::size_t(W) + std::size_t(x);
      env.radiance[k] = float(L);
      weights[k] = float(L * map.row_solid_angle(y));
    }
  env.dist = std::make_shared<SphericalDistribution>(
      Kind::LatLong, std::make_shared<PyramidDistribution2D>(weights.data(), W, H));
  return env;
}

Mat3 rotation_y(double deg) {
  const double a = deg * kPi / 180.0, c = std::cos(a), s = std::sin(a);
  return Mat3(c, 0, s, 0, 1, 0, -s, 0, c);
}
Mat3 rotation_x(double deg) {
  const double a = deg * kPi / 180.0, c = std::cos(a), s = std::sin(a);
  return Mat3(1, 0, 0, 0, c, -s, 0, s, c);
}

Vec3 wo_at(double theta_deg, double phi_deg = 30.0) {
  const double t = theta_deg * kPi / 180.0, p = phi_deg * kPi / 180.0;
  return Vec3(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
}

bool finite3(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct Setup {
  std::string name;
  std::function<std::unique_ptr<Material>()> make;
};

void PrintTo(const Setup& s, std::ostream* os) { *os << s.name; }

std::vector<Setup> setups() {
  return {{"Diffuse", [] { return make_diffuse(Vec3(0.7, 0.6, 0.5)); }},
          {"GlossyConductor", [] { return make_conductor(Vec3(0.2, 0.4, 1.4), Vec3(3.9, 2.4, 1.6), 0.1); }},
          {"RoughPlastic", [] { return make_plastic(Vec3(0.5, 0.3, 0.2), 0.3, 1.5); }}};
}

// The shading configuration shared by the tests: a tilted normal, a rotated environment.
const Vec3 kNormal = Vec3(0.3, 0.8, 0.2).normalized();
const Mat3 kWorldFromTable = compose(rotation_y(30.0), rotation_x(20.0));
const Vec3 kSunDir = Vec3(0.5, 0.6, 0.3);

// Integral of f_cos (channel 0) over texel (x, y), by an n x n midpoint rule uniform in solid angle.
double texel_integral(const Material& m, const Frame& frame, const Vec3& wo, int x, int y, int W, int H,
                      const Mat3& world_from_table, int n) {
  const double z0 = std::cos(kPi * y / H), z1 = std::cos(kPi * (y + 1) / H);
  const double omega = (kTwoPi / W) * (z0 - z1);
  double s = 0.0;
  for (int b = 0; b < n; ++b)
    for (int a = 0; a < n; ++a) {
      const double u = (x + (a + 0.5) / n) / W, z = z0 + (z1 - z0) * (b + 0.5) / n;
      const double lon = kPi - kTwoPi * u, r = safe_sqrt(1.0 - z * z);
      const Vec3 d(std::sin(lon) * r, z, std::cos(lon) * r);
      s += m.eval(wo, frame.to_local(apply(world_from_table, d))).x;
    }
  return s * omega / (n * n);
}

class Product : public ::testing::TestWithParam<Setup> {};

// pdf(sample direction) equals the sampled pdf; directions are unit and finite; the pdf integrates to 1 over the
// sphere (sum over texels of the constant pdf x texel solid angle).
TEST_P(Product, PdfMatchesSampleAndIsNormalised) {
  const TestEnv env = make_env(128, 64, 200.0, kSunDir, 3.0);
  const auto material = GetParam().make();
  const Frame frame = Frame::from_normal(kNormal);
  for (int resolution : {1, 4, 8, 16, 32, 64, 128})
  for (int points : {0, 3}) {
    SCOPED_TRACE("resolution " + std::to_string(resolution) + " points " + std::to_string(points));
    ProductSampler::Options options;
    options.points_per_axis = points;
    ProductSampler ps(*env.dist, kWorldFromTable, resolution, options);
    EXPECT_EQ(ps.coarse_width(), resolution);
    EXPECT_EQ(ps.points_per_axis(), points == 0 ? (resolution <= 16 ? 2 : 1) : points);
    for (double theta_o : {0.0, 50.0, 85.0}) {
      const Vec3 wo = wo_at(theta_o);
      ps.prepare(*material, frame, wo);
      ASSERT_TRUE(ps.valid());
      std::mt19937_64 rng(11);
      for (int s = 0; s < 20000; ++s) {
        Vec3 wi;
        double pdf = 0.0;
        Vec3 f;
        ASSERT_TRUE(ps.sample(Vec2(uniform53(rng), uniform53(rng)), wi, pdf, f));
        ASSERT_TRUE(finite3(wi) && finite3(f));
        ASSERT_NEAR(wi.length(), 1.0, 1e-12);
        ASSERT_GT(pdf, 0.0);
        ASSERT_NEAR(ps.pdf(wi), pdf, 1e-6 * pdf);
      }
      double total = 0.0;
      for (int y = 0; y < env.height; ++y)
        for (int x = 0; x < env.width; ++x)
          total += ps.pdf(apply(kWorldFromTable, texel_centre(x, y, env.width, env.height))) *
                   env.dist->texel_solid_angle(x, y);
      EXPECT_NEAR(total, 1.0, 1e-6);  // float node sums: each in-node ratio leaf / node is within ~1e-7
    }
  }
}

// Chi-square of the samples against pdf() on cells that split every texel into 2 x 2 equal solid angles (half the
// longitude span x half the cos theta span): tests the discrete choice and the uniformity inside the texel.
TEST_P(Product, ChiSquareUnderSunProbe) {
  const int W = 64, H = 32;
  const TestEnv env = make_env(W, H, 1000.0, kSunDir, 4.0);
  const auto material = GetParam().make();
  const Frame frame = Frame::from_normal(kNormal);
  const Mat3 table_from_world = transposed(kWorldFromTable);
  int tests = 0;
  for (int resolution : {8, 32}) {
    for (double theta_o : {20.0, 70.0}) {
      ++tests;
      SCOPED_TRACE("resolution " + std::to_string(resolution) + " theta_o " + std::to_string(theta_o));
      ProductSampler ps(*env.dist, kWorldFromTable, resolution);
      ps.prepare(*material, frame, wo_at(theta_o));
      ASSERT_TRUE(ps.valid());
      constexpr std::size_t n = 1000000;
      std::vector<double> observed(std::size_t(W * H * 4), 0.0), expected(observed.size(), 0.0);
      std::mt19937_64 rng(2024 + std::uint64_t(resolution));
      for (std::size_t s = 0; s < n; ++s) {
        Vec3 wi;
        double pdf = 0.0;
        ASSERT_TRUE(ps.sample(Vec2(uniform53(rng), uniform53(rng)), wi, pdf));
        const Vec3 d = apply(table_from_world, wi);
        int x = 0, y = 0;
        env.dist->texel_of(d, x, y);
        const Vec2 uv = LatLongMap::uv_from_direction(d);
        const double fx = uv.x * W - x;
        const double z0 = std::cos(kPi * y / H), z1 = std::cos(kPi * (y + 1) / H);
        const double fy = (z0 - d.y) / (z0 - z1);
        const int sub = (fx >= 0.5 ? 1 : 0) + (fy >= 0.5 ? 2 : 0);
        observed[(std::size_t(y) * std::size_t(W) + std::size_t(x)) * 4 + std::size_t(sub)] += 1.0;
      }
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          const double p = ps.pdf(apply(kWorldFromTable, texel_centre(x, y, W, H))) * env.dist->texel_solid_angle(x, y);
          for (int sub = 0; sub < 4; ++sub)
            expected[(std::size_t(y) * std::size_t(W) + std::size_t(x)) * 4 + std::size_t(sub)] = 0.25 * p * double(n);
        }
      const chi2::Result r = chi2::test(observed, expected, chi2::sidak_alpha(0.01, 4 * 3));
      EXPECT_TRUE(r.passed) << r.message;
    }
  }
  (void)tests;
}

// Mean and variance per sample of f_cos L / pdf (channel 0) over n samples at the prepared shading point.
/// pdf_mismatches counts samples whose pdf() differs from the drawn pdf by more than 1e-6 relative.
struct Moments {
  double mean = 0.0, variance = 0.0;
  std::size_t pdf_mismatches = 0;
};
Moments product_moments(const ProductSampler& ps, const TestEnv& env, std::size_t n, std::uint64_t seed) {
  Moments m;
  const Mat3 table_from_world = transposed(kWorldFromTable);
  std::mt19937_64 rng(seed);
  double s = 0.0, s2 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    Vec3 wi, f;
    double pdf = 0.0, value = 0.0;
    if (ps.sample(Vec2(uniform53(rng), uniform53(rng)), wi, pdf, f)) {
      if (!(std::abs(ps.pdf(wi) - pdf) <= 1e-6 * pdf)) ++m.pdf_mismatches;
      int x = 0, y = 0;
      env.dist->texel_of(apply(table_from_world, wi), x, y);
      value = f.x * env.L(x, y) / pdf;
    }
    s += value;
    s2 += value * value;
  }
  m.mean = s / double(n);
  m.variance = std::max(0.0, s2 / double(n) - m.mean * m.mean);
  return m;
}

// E[f_cos L / pdf] equals sum over texels of L x (integral of f_cos over the texel) within 4 sigma (+ 0.2% for the
// quadrature), for several resolutions; and for a glossy lobe the product estimator has lower variance than plain
// environment sampling (resolution 1).
TEST_P(Product, UnbiasedAgainstQuadrature) {
  const int W = 64, H = 32;
  const TestEnv env = make_env(W, H, 500.0, kSunDir, 4.0);
  const auto material = GetParam().make();
  const Frame frame = Frame::from_normal(kNormal);
  const Vec3 wo = wo_at(35.0);
  double reference = 0.0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      reference += env.L(x, y) * texel_integral(*material, frame, wo, x, y, W, H, kWorldFromTable, 24);
  double variance_env = 0.0, variance_product = 0.0;
  for (int resolution : {1, 8, 32, 64}) {
    SCOPED_TRACE("resolution " + std::to_string(resolution));
    ProductSampler ps(*env.dist, kWorldFromTable, resolution);
    ps.prepare(*material, frame, wo);
    constexpr std::size_t n = 200000;
    const Moments m = product_moments(ps, env, n, 77);
    const double mean = m.mean, var = m.variance;
    const double sigma = std::sqrt(var / double(n));
    EXPECT_NEAR(mean, reference, 4.0 * sigma + 2e-3 * reference)
        << "mean " << mean << " reference " << reference << " sigma " << sigma;
    if (resolution == 1) variance_env = var;
    if (resolution == 32) variance_product = var;
    std::printf("[ %s ] resolution %3d: mean %.6g (reference %.6g), variance per sample %.4g\n",
                GetParam().name.c_str(), resolution, mean, reference, var);
  }
  EXPECT_LT(variance_product, variance_env);
}

// A 1e6 sun in one texel of a 256 x 128 map, grazing and normal wo, every material: nothing is NaN or inf.
TEST_P(Product, NoNanUnderBrightSun) {
  const TestEnv env = make_env(256, 128, 1e6, Vec3(-0.2, 0.9, 0.1), 0.0);
  const auto material = GetParam().make();
  for (const Vec3& normal : {kNormal, Vec3(0, 1, 0), Vec3(0, -1, 0)}) {
    const Frame frame = Frame::from_normal(normal);
    for (int resolution : {2, 32, 256}) {
      ProductSampler ps(*env.dist, kWorldFromTable, resolution);
      for (double theta_o : {0.0, 60.0, 89.99, 89.9999999}) {
        ps.prepare(*material, frame, wo_at(theta_o));
        if (!ps.valid()) continue;
        std::mt19937_64 rng(5);
        for (int k = 0; k < 20000; ++k) {
          Vec3 wi, f;
          double pdf = 0.0;
          const Vec2 u = k < 4 ? Vec2(k & 1 ? kOneMinusEpsilon : 0.0, k & 2 ? 1.0 : 0.0)
                               : Vec2(uniform53(rng), uniform53(rng));
          if (!ps.sample(u, wi, pdf, f)) continue;
          ASSERT_TRUE(finite3(wi) && finite3(f) && std::isfinite(pdf) && pdf > 0.0);
          ASSERT_TRUE(std::isfinite(f.x / pdf * 1e6));
          ASSERT_TRUE(std::isfinite(ps.pdf(wi)));
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Materials, Product, ::testing::ValuesIn(setups()),
                         [](const ::testing::TestParamInfo<Setup>& param_info) { return param_info.param.name; });

TEST(ProductSampler, InvalidInputs) {
  const TestEnv env = make_env(32, 16, 10.0, kSunDir, 5.0);
  ProductSampler ps(*env.dist, identity3(), 8);
  const Frame frame = Frame::from_normal(Vec3(0, 1, 0));
  const auto diffuse = make_diffuse(Vec3(0.5));
  Vec3 wi;
  double pdf = 0.0;
  // wo below the horizon, a pure delta material: not valid, nothing sampled, pdf 0.
  ps.prepare(*diffuse, frame, Vec3(0, 0.6, -0.8));
  EXPECT_FALSE(ps.valid());
  EXPECT_FALSE(ps.sample(Vec2(0.5, 0.5), wi, pdf));
  EXPECT_EQ(ps.pdf(Vec3(0, 1, 0)), 0.0);
  const auto mirror = make_mirror(Vec3(1.0));
  ps.prepare(*mirror, frame, Vec3(0, 0, 1));
  EXPECT_FALSE(ps.valid());
  // Valid again; directions below the shading horizon have pdf 0 (whole coarse nodes below it) or are never drawn.
  ps.prepare(*diffuse, frame, Vec3(0, 0, 1));
  EXPECT_TRUE(ps.valid());
  EXPECT_EQ(ps.pdf(Vec3(0, -1, 0)), 0.0);
  EXPECT_EQ(ps.pdf(Vec3(0, 0, 0)), 0.0);
  EXPECT_EQ(ps.pdf(Vec3(std::nan(""), 1, 0)), 0.0);
  EXPECT_GT(ps.pdf(Vec3(0, 1, 0)), 0.0);
  // Resolution rounding to the nearest level.
  EXPECT_EQ(ProductSampler(*env.dist, identity3(), 1).coarse_width(), 1);
  EXPECT_EQ(ProductSampler(*env.dist, identity3(), 7).coarse_width(), 8);
  EXPECT_EQ(ProductSampler(*env.dist, identity3(), 1000).coarse_width(), 32);
  EXPECT_EQ(ProductSampler(*env.dist, identity3(), 0).coarse_width(), 1);
  // The environment must be hierarchical.
  std::vector<float> w(32 * 16, 1.0f);
  const SphericalDistribution cdf(Kind::LatLong, std::make_shared<CdfDistribution2D>(w.data(), 32, 16));
  EXPECT_THROW(ProductSampler(cdf, identity3(), 8), Error);
  // HEALPix tables: its layout puts base pixels side by side that are not neighbours on the sphere, so node
  // bounds would be wrong; refused with the reason rather than sampled with a bias.
  std::vector<float> hw(16 * 12, 1.0f);
  const SphericalDistribution healpix(Kind::HEALPix, std::make_shared<PyramidDistribution2D>(hw.data(), 16, 12));
  std::string message;
  try {
    ProductSampler refused(healpix, identity3(), 8);
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("needs a latlong or octahedral table, not healpix"), std::string::npos) << message;
}

// White furnace on both bake grids: a constant environment L = 1 and a diffuse albedo rho give E[f_cos L / pdf]
// = rho (within 4 sigma); pdf(sample) == sample pdf; the pdf integrates to 1 over the grid's texels.
TEST(ProductSampler, WhiteFurnaceLatLongAndOctahedral) {
  for (Kind grid : {Kind::LatLong, Kind::Octahedral}) {
    const int W = grid == Kind::LatLong ? 128 : 64, H = 64;
    std::vector<float> w(std::size_t(W) * std::size_t(H));
    const LatLongMap latlong(W, H);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        w[std::size_t(y) * std::size_t(W) + std::size_t(x)] =
            float(grid == Kind::LatLong ? latlong.row_solid_angle(y) : kFourPi / (W * H));
    const SphericalDistribution env(grid, std::make_shared<PyramidDistribution2D>(w.data(), W, H));
    const auto centre = [&](int x, int y) {
      if (grid == Kind::LatLong) return texel_centre(x, y, W, H);
      Vec3 d;
      OctahedralMap(W).to_direction(Vec2(x + 0.5, y + 0.5), d);
      return d;
    };
    const double rho = 0.7;
    const auto diffuse = make_diffuse(Vec3(rho));
    for (int resolution : {1, 8, 32}) {
      SCOPED_TRACE(std::string(grid == Kind::LatLong ? "latlong" : "octahedral") + " resolution " +
                   std::to_string(resolution));
      ProductSampler ps(env, kWorldFromTable, resolution);
      const Frame frame = Frame::from_normal(kNormal);
      ps.prepare(*diffuse, frame, wo_at(40.0));
      ASSERT_TRUE(ps.valid());
      double total = 0.0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) total += ps.pdf(apply(kWorldFromTable, centre(x, y))) * env.texel_solid_angle(x, y);
      EXPECT_NEAR(total, 1.0, 1e-6);
      std::mt19937_64 rng(31);
      constexpr int n = 100000;
      double s = 0.0, s2 = 0.0;
      for (int k = 0; k < n; ++k) {
        Vec3 wi, f;
        double pdf = 0.0, v = 0.0;
        if (ps.sample(Vec2(uniform53(rng), uniform53(rng)), wi, pdf, f)) {
          ASSERT_NEAR(ps.pdf(wi), pdf, 1e-6 * pdf);
          v = f.x / pdf;
        }
        s += v;
        s2 += v * v;
      }
      const double mean = s / n, sigma = std::sqrt(std::max(0.0, s2 / n - mean * mean) / n);
      EXPECT_NEAR(mean, rho, 4.0 * sigma + 1e-9) << "sigma " << sigma;
    }
  }
}

// Lobe refinement (a GGX lobe gets a level of its own, at most the coarse one, mixed with the
// floored coarse table): with narrow conductors and plastics, normals at the pole and near the longitude seam
// (the lobe rectangle wraps), lobe mode is active; pdf(sample) == sample pdf, the pdf integrates to 1, a
// chi-square-free check of unbiasedness against the quadrature, and eval-based b (lobe_proxy off) as well.
TEST(ProductSampler, LobeRefinementIsConsistentAndUnbiased) {
  const int W = 256, H = 128;
  const TestEnv env = make_env(W, H, 300.0, kSunDir, 2.0);
  const std::vector<std::function<std::unique_ptr<Material>()>> materials = {
      [] { return make_conductor(Vec3(0.2, 0.4, 1.4), Vec3(3.9, 2.4, 1.6), 0.05); },
      [] { return make_plastic(Vec3(0.5, 0.3, 0.2), 0.1, 1.5); }};
  const Vec3 normals[] = {kNormal, apply(kWorldFromTable, Vec3(0, 1, 0)), apply(kWorldFromTable, Vec3(0, 0, -1)),
                          apply(kWorldFromTable, Vec3(0.02, 0.3, -1).normalized())};
  int active = 0;
  // {lobe_proxy, lobe_descent}: the default, the proxy with env-only descent, and eval-based b and descent.
  for (const auto& [proxy, descent] : {std::pair{true, true}, std::pair{true, false}, std::pair{false, true}})
    for (const auto& make : materials)
      for (const Vec3& normal : normals)
        for (double theta_o : {0.0, 45.0}) {
          const auto material = make();
          ProductSampler::Options options;
          options.lobe_proxy = proxy;
          options.lobe_descent = descent;
          ProductSampler ps(*env.dist, kWorldFromTable, 16, options);
          const Frame frame = Frame::from_normal(normal);
          const Vec3 wo = wo_at(theta_o);
          ps.prepare(*material, frame, wo);
          ASSERT_TRUE(ps.valid());
          if (ps.lobe_level() >= 0) {
            ++active;
            EXPECT_LE(ps.lobe_level(), ps.coarse_level());
            EXPECT_GT(ps.lobe_node_count(), 0);
          }
          double total = 0.0;
          for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
              total += ps.pdf(apply(kWorldFromTable, texel_centre(x, y, W, H))) * env.dist->texel_solid_angle(x, y);
          EXPECT_NEAR(total, 1.0, 1e-6);
          double reference = 0.0;
          for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
              reference += env.L(x, y) * texel_integral(*material, frame, wo, x, y, W, H, kWorldFromTable, 6);
          constexpr std::size_t n = 100000;
          const Moments m = product_moments(ps, env, n, 99);
          EXPECT_EQ(m.pdf_mismatches, 0u);
          const double mean = m.mean, sigma = std::sqrt(m.variance / double(n));
          EXPECT_NEAR(mean, reference, 5.0 * sigma + 1e-2 * reference)
              << "proxy " << proxy << " descent " << descent << " theta_o " << theta_o << " sigma " << sigma;
        }
  EXPECT_GT(active, 12);  // the narrow lobes do take the lobe path
}

// Lobe descent is what lets a lobe narrower than the lobe nodes be followed down to the texels: for GGX alpha
// 0.02 and 0.05 under a sky (no sun: the variance is the lobe's, not a sun's), it lowers the variance per sample
// at least 2x against env-only descent below the lobe level.
TEST(ProductSampler, LobeDescentLowersTheVarianceOfNarrowLobes) {
  const TestEnv env = make_env(512, 256, 0.0, kSunDir, 0.0);
  const Frame frame = Frame::from_normal(kNormal);
  for (double alpha : {0.02, 0.05}) {
    const auto conductor = make_conductor(Vec3(0.2, 0.4, 1.4), Vec3(3.9, 2.4, 1.6), alpha);
    double variance[2] = {0.0, 0.0};
    for (int descent = 0; descent < 2; ++descent) {
      ProductSampler::Options options;
      options.lobe_descent = descent == 1;
      ProductSampler ps(*env.dist, kWorldFromTable, 8, options);
      ps.prepare(*conductor, frame, wo_at(30.0));
      ASSERT_TRUE(ps.valid());
      ASSERT_GE(ps.lobe_level(), 0);
      variance[descent] = product_moments(ps, env, 100000, 5).variance;
    }
    std::printf("[ alpha %.2f ] variance per sample: env-only descent %.4g, lobe descent %.4g\n", alpha, variance[0],
                variance[1]);
    EXPECT_LT(2.0 * variance[1], variance[0]) << "alpha " << alpha;
  }
}

// Table reuse: reusable() accepts the same material within the angle (and half the lobe's width) only; a table
// prepared at one point and used at another within the angle is a density that is positive wherever the new
// point's BSDF is, so f_cos L / pdf at the NEW point is unbiased against its quadrature.
TEST(ProductSampler, ReusedTableStaysUnbiasedAtTheNewPoint) {
  const int W = 128, H = 64;
  const TestEnv env = make_env(W, H, 300.0, kSunDir, 3.0);
  const Mat3 table_from_world = transposed(kWorldFromTable);
  const auto rotate = [](const Vec3& v, const Vec3& axis, double angle) {  // Rodrigues
    const Vec3 k = axis.normalized();
    return v * std::cos(angle) + (k % v) * std::sin(angle) + k * ((k ^ v) * (1.0 - std::cos(angle)));
  };
  const std::vector<std::function<std::unique_ptr<Material>()>> materials = {
      [] { return make_diffuse(Vec3(0.7, 0.6, 0.5)); },
      [] { return make_conductor(Vec3(0.2, 0.4, 1.4), Vec3(3.9, 2.4, 1.6), 0.3); },
      [] { return make_plastic(Vec3(0.5, 0.3, 0.2), 0.1, 1.5); }};
  ProductSampler::Options options;
  options.reuse_angle = 0.3;
  for (const auto& make : materials)
    for (int resolution : {8, 32}) {
      const auto material = make();
      const auto other = make();
      ProductSampler ps(*env.dist, kWorldFromTable, resolution, options);
      const Frame frame_a = Frame::from_normal(kNormal);
      const Vec3 wo_world = frame_a.to_world(wo_at(50.0));
      ps.prepare(*material, frame_a, frame_a.to_local(wo_world));
      ASSERT_TRUE(ps.valid());
      // The allowed angle is min(0.3, half the lobe's width); find it by bisection on reusable().
      const Vec3 axis = Vec3(0.3, -0.5, 0.8) % kNormal;
      double lo = 0.0, hi = 0.5;
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        const Frame f = Frame::from_normal(rotate(kNormal, axis, mid));
        (ps.reusable(*material, f, f.to_local(wo_world)) ? lo : hi) = mid;
      }
      EXPECT_GT(lo, 0.0);
      EXPECT_LE(lo, 0.3 + 1e-9);
      EXPECT_FALSE(ps.reusable(*other, frame_a, frame_a.to_local(wo_world)));  // another material object
      EXPECT_TRUE(ps.reusable(*material, frame_a, frame_a.to_local(wo_world)));
      // A point at 0.9 x the allowed angle, its view direction turned as well.
      const Frame frame_b = Frame::from_normal(rotate(kNormal, axis, 0.9 * lo));
      const Vec3 wo_b = frame_b.to_local(rotate(wo_world, axis, 0.5 * lo));
      ASSERT_TRUE(ps.reusable(*material, frame_b, wo_b));
      double reference = 0.0;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          reference += env.L(x, y) * texel_integral(*material, frame_b, wo_b, x, y, W, H, kWorldFromTable, 8);
      std::mt19937_64 rng(17);
      constexpr int n = 200000;
      double s = 0.0, s2 = 0.0;
      for (int k = 0; k < n; ++k) {
        Vec3 wi;
        double pdf = 0.0, v = 0.0;
        if (ps.sample(Vec2(uniform53(rng), uniform53(rng)), wi, pdf)) {
          int x = 0, y = 0;
          env.dist->texel_of(apply(table_from_world, wi), x, y);
          v = material->eval(wo_b, frame_b.to_local(wi)).x * env.L(x, y) / pdf;
        }
        s += v;
        s2 += v * v;
      }
      const double mean = s / n, sigma = std::sqrt(std::max(0.0, s2 / n - mean * mean) / n);
      EXPECT_NEAR(mean, reference, 5.0 * sigma + 1e-2 * reference) << "resolution " << resolution;
      // Positivity: every direction where the new point's BSDF is positive has a positive density.
      for (int k = 0; k < 20000; ++k) {
        const double z = uniform53(rng), phi = kTwoPi * uniform53(rng), r = safe_sqrt(1.0 - z * z);
        const Vec3 wi_local(r * std::cos(phi), r * std::sin(phi), z);
        if (!(material->eval(wo_b, wi_local).x > 0.0)) continue;
        ASSERT_GT(ps.pdf(frame_b.to_world(wi_local)), 0.0);
      }
    }
  // Reuse off: never reusable.
  ProductSampler off(*env.dist, kWorldFromTable, 8);
  const auto diffuse = make_diffuse(Vec3(0.5));
  off.prepare(*diffuse, Frame::from_normal(kNormal), wo_at(20.0));
  EXPECT_FALSE(off.reusable(*diffuse, Frame::from_normal(kNormal), wo_at(20.0)));
}

// At resolution 1 the product table is a single node: the sampler is exactly environment sampling.
TEST(ProductSampler, ResolutionOneIsEnvironmentSampling) {
  const TestEnv env = make_env(64, 32, 100.0, kSunDir, 5.0);
  ProductSampler ps(*env.dist, kWorldFromTable, 1);
  const auto diffuse = make_diffuse(Vec3(0.5));
  ps.prepare(*diffuse, Frame::from_normal(kNormal), Vec3(0, 0, 1));
  const Mat3 table_from_world = transposed(kWorldFromTable);
  std::mt19937_64 rng(8);
  for (int k = 0; k < 10000; ++k) {
    const Vec2 u(uniform53(rng), uniform53(rng));
    Vec3 wi;
    double pdf = 0.0;
    ASSERT_TRUE(ps.sample(u, wi, pdf));
    const DirectionSample e = env.dist->sample(u);
    ASSERT_NEAR((apply(table_from_world, wi) - e.direction).length(), 0.0, 1e-9);
    ASSERT_NEAR(pdf, e.pdf, 1e-6 * e.pdf);
  }
}

}  // namespace
}  // namespace envkit::render
