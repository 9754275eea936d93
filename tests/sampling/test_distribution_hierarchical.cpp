// Tests of hierarchical sample warping through a sum pyramid (distribution_hierarchical.h).
#include <envkit/sampling/distribution_hierarchical.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <array>
#include <cfloat>
#include <cstring>
#include <limits>
#include <memory>
#include <random>

#include "chi2.h"

using namespace envkit;
using testmaps::TestMap;

namespace {

std::uint64_t seed_of(const std::string& name) {  // FNV-1a: a stable seed per test map
  std::uint64_t h = 1469598103934665603ull;
  for (char c : name) h = (h ^ std::uint8_t(c)) * 1099511628211ull;
  return h ^ 0x9b1d4ull;
}

// Chi-square tests run by this executable: one per standard map.
const int kChi2Tests = int(testmaps::standard_maps().size());
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

std::unique_ptr<HierarchicalDistribution2D> build(const TestMap& m) {
  return std::make_unique<HierarchicalDistribution2D>(m.weights.data(), m.width, m.height);
}

}  // namespace

class HierarchicalMaps : public ::testing::TestWithParam<TestMap> {};

TEST_P(HierarchicalMaps, ChiSquare) {
  const TestMap& m = GetParam();
  const chi2::Result r = testmaps::chi_square(*build(m), m, kAlpha, seed_of(m.name));
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
}

TEST_P(HierarchicalMaps, PdfIntegratesToOne) { EXPECT_EQ(testmaps::check_normalised(*build(GetParam())), ""); }

TEST_P(HierarchicalMaps, PdfMatchesWeights) {
  // pdf is w / integral; the drawn probability is a product of at most 2 x levels float ratios.
  EXPECT_EQ(testmaps::check_matches_weights(*build(GetParam()), GetParam(), 2e-6), "");
}

TEST_P(HierarchicalMaps, SamplesAreConsistent) {
  EXPECT_EQ(testmaps::check_samples(*build(GetParam()), GetParam(), 20000, seed_of(GetParam().name) + 1), "");
}

TEST_P(HierarchicalMaps, InvertRoundTrips) {
  EXPECT_EQ(testmaps::check_invert(*build(GetParam()), 20000, seed_of(GetParam().name) + 2), "");
}

// sample_texel() and pick() are sample() before uv is formed (see testmaps::check_sample_texel).
TEST_P(HierarchicalMaps, SampleTexelIsSampleBeforeUv) {
  EXPECT_EQ(testmaps::check_sample_texel(*build(GetParam()), GetParam().width, GetParam().height), "");
}

TEST_P(HierarchicalMaps, PdfIsZeroOutside) { EXPECT_EQ(testmaps::check_pdf_outside(*build(GetParam())), ""); }

TEST_P(HierarchicalMaps, ReportsFallbacks) {
  const TestMap& m = GetParam();
  const auto d = build(m);
  bool all_zero = true;
  for (float w : m.weights) all_zero &= !(w > 0.0f);
  EXPECT_EQ(d->used_uniform_fallback(), all_zero);
  EXPECT_EQ(d->uniform_fallback_rows(), 0);  // zero rows need no fallback: their nodes are never entered
  EXPECT_EQ(d->unreachable_texels(), 0u);
  EXPECT_GT(d->bytes(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Maps, HierarchicalMaps, ::testing::ValuesIn(testmaps::standard_maps()), testmaps::MapName());

TEST(HierarchicalDistribution2D, LevelsForAnySize) {
  const std::vector<float> w(64 * 64, 1.0f);
  const auto levels = [&](int W, int H) { return HierarchicalDistribution2D(w.data(), W, H).levels(); };
  EXPECT_EQ(levels(1, 1), 1);
  EXPECT_EQ(levels(2, 1), 1);
  EXPECT_EQ(levels(3, 2), 2);
  EXPECT_EQ(levels(64, 32), 6);
  EXPECT_EQ(levels(33, 17), 6);
  EXPECT_EQ(levels(1, 9), 4);
}

TEST(HierarchicalDistribution2D, ConstantPowerOfTwoMapIsTheIdentityWarp) {
  // Every choice is 1/2, an exact re-scaling: the warp is the identity, which is why stratification survives.
  const std::vector<float> w(32 * 16, 0.3f);
  const HierarchicalDistribution2D d(w.data(), 32, 16);
  std::mt19937_64 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
    const DistributionSample s = d.sample(u);
    EXPECT_NEAR(s.uv.x, u.x, 1e-12);
    EXPECT_NEAR(s.uv.y, u.y, 1e-12);
    EXPECT_NEAR(s.pdf, 1.0, 1e-12);
  }
}

TEST(HierarchicalDistribution2D, PreservesStratification) {
  // The preimage of every pyramid node is an axis-aligned rectangle of u, so a jittered stratification keeps its
  // low discrepancy after warping: the per-node count errors come only from strata cut by rectangle edges. Over
  // the 4x4-texel nodes of a 32x32 smooth map, their sum of squares must be far below the ~N of independent
  // samples (a multinomial's sum of N p (1 - p)).
  const int W = 32, H = 32, strata = 64;
  std::vector<float> w(W * H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) w[std::size_t(y) * W + std::size_t(x)] = float(1.0 + x + 0.5 * y);
  const HierarchicalDistribution2D d(w.data(), W, H);
  double sum = 0.0;
  for (float v : w) sum += v;
  const double n = strata * strata;
  const auto squared_error = [&](auto&& draw) {
    std::vector<double> count(64, 0.0), expected(64, 0.0);
    for (int j = 0; j < strata; ++j)
      for (int i = 0; i < strata; ++i) {
        const DistributionSample s = d.sample(draw(i, j));
        count[std::size_t(s.y / 4) * 8 + std::size_t(s.x / 4)] += 1.0;
      }
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        expected[std::size_t(y / 4) * 8 + std::size_t(x / 4)] += w[std::size_t(y) * W + std::size_t(x)] / sum * n;
    double sse = 0.0;
    for (int c = 0; c < 64; ++c)
      sse += (count[std::size_t(c)] - expected[std::size_t(c)]) * (count[std::size_t(c)] - expected[std::size_t(c)]);
    return sse;
  };
  std::mt19937_64 rng(5);
  const double stratified = squared_error([&](int i, int j) {
    return Vec2((i + testmaps::uniform53(rng)) / strata, (j + testmaps::uniform53(rng)) / strata);
  });
  const double independent =
      squared_error([&](int, int) { return Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)); });
  EXPECT_LT(stratified, 0.1 * n) << "independent: " << independent;
  EXPECT_GT(independent, 0.5 * n);  // the control: iid samples do not have this property
}

TEST(HierarchicalDistribution2D, KeepsTinyTexelsBesideASun) {
  // A 1e6 sun among 1e-3 texels in 2D: each node compares only its own children, so every texel (1e-9 of the
  // map) is drawn with probability w / sum to ~1e-6, including those right of and below the sun, whose share of
  // their parent is below 2^-24 (reachable because decisions are clamped to 1 - 2^-53, not 1 - 2^-24).
  const int W = 64, H = 32;
  std::vector<float> w(std::size_t(W) * H, 1e-3f);
  w[std::size_t(20) * W + 40] = 1e6f;
  const HierarchicalDistribution2D d(w.data(), W, H);
  double sum = 0.0;
  for (float v : w) sum += v;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double ideal = w[std::size_t(y) * W + std::size_t(x)] / sum, drawn = d.texel_probability(x, y);
      ASSERT_NEAR(drawn, ideal, 2e-6 * ideal) << x << "," << y;
    }
  // The sun's right-hand neighbour, reached by inverting a point inside it and sampling back.
  const Vec2 inside((41 + 0.5) / W, (20 + 0.5) / H);
  const DistributionSample s = d.sample(d.invert(inside));
  EXPECT_EQ(s.x, 41);
  EXPECT_EQ(s.y, 20);
}

TEST(HierarchicalDistribution2D, HugeTotalsAreScaledNotOverflowed) {
  std::vector<float> w(16 * 8, FLT_MAX);
  w[3] = std::numeric_limits<float>::infinity();
  w[4] = 1.0f;
  const HierarchicalDistribution2D d(w.data(), 16, 8);
  EXPECT_TRUE(std::isfinite(d.integral()));
  EXPECT_EQ(testmaps::check_normalised(d), "");
  std::mt19937_64 rng(9);
  for (int i = 0; i < 1000; ++i) {
    const DistributionSample s = d.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0);
    ASSERT_NEAR(d.texel_probability(s.x, s.y) * 16 * 8, s.pdf, 1e-6);
  }
}

TEST(HierarchicalDistribution2D, RejectsBadSizes) {
  const float w = 1.0f;
  EXPECT_THROW(HierarchicalDistribution2D(&w, 0, 1), Error);
  EXPECT_THROW(HierarchicalDistribution2D(nullptr, 1, 1), Error);
}

TEST(HierarchicalDistribution2D, DeterministicAcrossThreadCounts) {
  const int W = 1000, H = 500;  // above the parallel threshold, not a power of two
  std::vector<float> w(std::size_t(W) * H);
  std::mt19937_64 rng(11);
  for (float& v : w) v = float(std::pow(10.0, 6.0 * testmaps::uniform53(rng) - 3.0));
  std::unique_ptr<HierarchicalDistribution2D> one, many;
  tbb::task_arena(1).execute([&] { one = std::make_unique<HierarchicalDistribution2D>(w.data(), W, H); });
  tbb::task_arena(2).execute([&] { many = std::make_unique<HierarchicalDistribution2D>(w.data(), W, H); });
  for (int i = 0; i < 20000; ++i) {
    const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
    const DistributionSample a = one->sample(u), b = many->sample(u);
    ASSERT_EQ(std::memcmp(&a.uv, &b.uv, sizeof(Vec2)), 0);
    ASSERT_EQ(std::memcmp(&a.pdf, &b.pdf, sizeof(double)), 0);
  }
  EXPECT_EQ(one->integral(), many->integral());
}
