// Tests of the alias-table distributions (distribution_alias.h).
#include <envkit/sampling/distribution_alias.h>
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
  return h ^ 0xa11a5ull;
}

// Chi-square tests run by this executable: one per standard map + the 1D test.
const int kChi2Tests = int(testmaps::standard_maps().size()) + 1;
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

std::unique_ptr<AliasDistribution2D> build(const TestMap& m) {
  return std::make_unique<AliasDistribution2D>(m.weights.data(), m.width, m.height);
}

}  // namespace

class AliasMaps : public ::testing::TestWithParam<TestMap> {};

TEST_P(AliasMaps, ChiSquare) {
  const TestMap& m = GetParam();
  const chi2::Result r = testmaps::chi_square(*build(m), m, kAlpha, seed_of(m.name));
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
}

TEST_P(AliasMaps, PdfIntegratesToOne) { EXPECT_EQ(testmaps::check_normalised(*build(GetParam())), ""); }

TEST_P(AliasMaps, PdfMatchesWeights) {
  // pdf is w / integral; what the float tables draw (texel_probability) agrees to float rounding.
  EXPECT_EQ(testmaps::check_matches_weights(*build(GetParam()), GetParam(), 1e-6), "");
}

TEST_P(AliasMaps, SamplesAreConsistent) {
  EXPECT_EQ(testmaps::check_samples(*build(GetParam()), GetParam(), 20000, seed_of(GetParam().name) + 1), "");
}

// sample_texel() and pick() are sample() before uv is formed (see testmaps::check_sample_texel).
TEST_P(AliasMaps, SampleTexelIsSampleBeforeUv) {
  EXPECT_EQ(testmaps::check_sample_texel(*build(GetParam()), GetParam().width, GetParam().height), "");
}

TEST_P(AliasMaps, PdfIsZeroOutside) { EXPECT_EQ(testmaps::check_pdf_outside(*build(GetParam())), ""); }

TEST_P(AliasMaps, CannotInvert) {
  const auto d = build(GetParam());
  EXPECT_FALSE(d->can_invert());
  EXPECT_THROW(d->invert(Vec2(0.5, 0.5)), Error);
}

TEST_P(AliasMaps, ReportsFallbacks) {
  const TestMap& m = GetParam();
  const auto d = build(m);
  int zero_rows = 0;
  bool all_zero = true;
  for (int y = 0; y < m.height; ++y) {
    bool row_zero = true;
    for (int x = 0; x < m.width; ++x)
      row_zero &= !(m.weights[std::size_t(y) * std::size_t(m.width) + std::size_t(x)] > 0.0f);
    zero_rows += row_zero;
    all_zero &= row_zero;
  }
  EXPECT_EQ(d->uniform_fallback_rows(), zero_rows);
  EXPECT_EQ(d->used_uniform_fallback(), all_zero);
  EXPECT_EQ(d->unreachable_texels(), 0u);
  EXPECT_EQ(d->bytes(), std::size_t(m.width) * m.height * 16 + std::size_t(m.height) * 8);
}

INSTANTIATE_TEST_SUITE_P(Maps, AliasMaps, ::testing::ValuesIn(testmaps::standard_maps()), testmaps::MapName());

TEST(AliasDistribution2D, KeepsTinyTexelsBesideASun) {
  // Floor texels 1e-9 of the row beside a 1e6 sun: an alias table stores each as its own small keep
  // probability, so it keeps float relative precision.
  const int W = 4096;
  std::vector<float> w(W, 1e-3f);
  w[1000] = 1e6f;
  const AliasDistribution2D d(w.data(), W, 1);
  double sum = 0.0;
  for (float v : w) sum += v;
  double worst = 0.0;
  for (int x = 990; x < 1100; ++x) {
    const double ideal = w[std::size_t(x)] / sum, drawn = d.texel_probability(x, 0);
    ASSERT_GT(drawn, 0.0) << x;
    worst = std::max(worst, std::abs(drawn - ideal) / ideal);
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(AliasDistribution2D, ManySmallDonationsKeepTheirPrecision) {
  // One texel twice as bright as 16383 others: it is the alias of them all and collects 16383 donations of
  // 1 - q = 6e-5. Stored as float q ~ 1 - 6e-5, each donation would carry up to 3e-8 of error (2.5e-4 relative
  // in total); stored two-sided they are exact to float relative precision.
  const int W = 16384;
  std::vector<float> w(W, 1.0f);
  w[777] = 2.0f;
  const AliasDistribution2D d(w.data(), W, 1);
  const double sum = W + 1.0;
  EXPECT_NEAR(d.texel_probability(777, 0), 2.0 / sum, 1e-6 * 2.0 / sum);
  EXPECT_NEAR(d.texel_probability(5, 0), 1.0 / sum, 1e-6 / sum);
}

TEST(AliasDistribution2D, InfiniteAndHugeWeightsStayFinite) {
  std::vector<float> w(8 * 4, 1.0f);
  w[5] = std::numeric_limits<float>::infinity();
  w[6] = FLT_MAX;
  const AliasDistribution2D d(w.data(), 8, 4);
  EXPECT_TRUE(std::isfinite(d.integral()));
  EXPECT_EQ(testmaps::check_normalised(d), "");
  const DistributionSample s = d.sample(Vec2(0.3, 0.3));
  EXPECT_TRUE(std::isfinite(s.pdf));
  EXPECT_TRUE(s.x == 5 || s.x == 6);
}

TEST(AliasDistribution2D, RejectsBadSizes) {
  const float w = 1.0f;
  EXPECT_THROW(AliasDistribution2D(&w, 0, 1), Error);
  EXPECT_THROW(AliasDistribution2D(nullptr, 1, 1), Error);
}

TEST(AliasDistribution2D, DeterministicAcrossThreadCounts) {
  const int W = 1024, H = 512;  // above the parallel threshold
  std::vector<float> w(std::size_t(W) * H);
  std::mt19937_64 rng(11);
  for (float& v : w) v = float(std::pow(10.0, 6.0 * testmaps::uniform53(rng) - 3.0));
  std::unique_ptr<AliasDistribution2D> one, many;
  tbb::task_arena(1).execute([&] { one = std::make_unique<AliasDistribution2D>(w.data(), W, H); });
  tbb::task_arena(2).execute([&] { many = std::make_unique<AliasDistribution2D>(w.data(), W, H); });
  for (int i = 0; i < 20000; ++i) {
    const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
    const DistributionSample a = one->sample(u), b = many->sample(u);
    ASSERT_EQ(std::memcmp(&a.uv, &b.uv, sizeof(Vec2)), 0);
    ASSERT_EQ(std::memcmp(&a.pdf, &b.pdf, sizeof(double)), 0);
  }
}

TEST(AliasTable1D, ChiSquareAndProbabilities) {
  std::vector<float> w = {0.0f, 3.0f, 1.0f, 0.0f, 0.0f, 2.0f, 1e-4f, 5.0f, 0.5f};
  const AliasTable1D d(w);
  const int n = int(w.size()), cells = 27;
  std::mt19937_64 rng(13);
  const std::size_t samples = 500000;
  const testmaps::Histogram h = testmaps::histogram(cells, 1, samples, [&] {
    const auto s = d.sample(testmaps::uniform53(rng));
    EXPECT_GT(w[std::size_t(s.index)], 0.0f);
    EXPECT_DOUBLE_EQ(s.pdf, d.pdf(s.x));
    return Vec2(s.x, 0.5);
  });
  const std::vector<double> ideal = testmaps::reference_probabilities(w);
  const std::vector<double> e = testmaps::expected_counts(ideal, n, 1, cells, 1, double(samples));
  const chi2::Result r = chi2::test(h.counts, e, kAlpha);
  EXPECT_TRUE(r.passed) << r.message;
  for (int i = 0; i < n; ++i)
    EXPECT_NEAR(d.bin_probability(i), ideal[std::size_t(i)], 1e-7 * ideal[std::size_t(i)] + 1e-15);
  EXPECT_NEAR(d.integral(), 11.5001 / 9, 1e-6);
  const AliasTable1D zero(std::vector<float>(4, 0.0f));
  EXPECT_TRUE(zero.used_uniform_fallback());
  EXPECT_DOUBLE_EQ(zero.pdf(0.3), 1.0);
}
