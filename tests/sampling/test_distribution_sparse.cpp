// Tests of the sparse distribution (distribution_sparse.h): the standard maps' checks on every map with light,
// and what only a sparse table does (texels off the list get nothing, a blob's values are checked).
#include <envkit/sampling/distribution_sparse.h>
#include <gtest/gtest.h>

#include <cstring>
#include <numeric>
#include <random>

#include "chi2.h"

using namespace envkit;
using testmaps::TestMap;
using testmaps::uniform53;

namespace {

const int kChi2Tests = int(testmaps::lit_standard_maps().size());
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

/// A standard map as a sparse table over all its texels (zero weights are dropped).
std::unique_ptr<SparseDistribution2D> build(const TestMap& m) {
  std::vector<std::uint64_t> texels(m.weights.size());
  std::iota(texels.begin(), texels.end(), std::uint64_t(0));
  return std::make_unique<SparseDistribution2D>(m.width, m.height, texels, m.weights);
}

std::uint64_t seed_of(const std::string& name) { return testmaps::seed_of(name, 0x5ea75eull); }

}  // namespace

class SparseMaps : public ::testing::TestWithParam<TestMap> {};

TEST_P(SparseMaps, ChiSquare) {
  const TestMap& m = GetParam();
  const chi2::Result r = testmaps::chi_square(*build(m), m, kAlpha, seed_of(m.name));
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
}

TEST_P(SparseMaps, PdfIntegratesToOne) { EXPECT_EQ(testmaps::check_normalised(*build(GetParam())), ""); }

TEST_P(SparseMaps, PdfMatchesWeights) {
  EXPECT_EQ(testmaps::check_matches_weights(*build(GetParam()), GetParam(), 1e-6), "");
}

TEST_P(SparseMaps, SamplesAreConsistent) {
  EXPECT_EQ(testmaps::check_samples(*build(GetParam()), GetParam(), 20000, seed_of(GetParam().name) + 1), "");
}

TEST_P(SparseMaps, InvertIsTheInverseOfSample) {
  EXPECT_EQ(testmaps::check_invert(*build(GetParam()), 5000, seed_of(GetParam().name) + 2), "");
}

TEST_P(SparseMaps, PdfIsZeroOutside) { EXPECT_EQ(testmaps::check_pdf_outside(*build(GetParam())), ""); }

INSTANTIATE_TEST_SUITE_P(Maps, SparseMaps, ::testing::ValuesIn(testmaps::lit_standard_maps()), testmaps::MapName());

TEST(SparseDistribution2D, TexelsOffTheListAreNeverDrawnAndHaveNoDensity) {
  const int W = 4096, H = 2048;
  const std::vector<std::uint64_t> texels = {5, 4096 + 7, 1000000, 4096ull * 2047 + 4095};
  const std::vector<float> weights = {1.0f, 3.0f, 0.0f, 4.0f};  // the zero-weight texel is dropped
  const SparseDistribution2D d(W, H, texels, weights);
  ASSERT_EQ(d.texels().size(), 3u);
  EXPECT_DOUBLE_EQ(d.texel_probability(5, 0), 1.0 / 8.0);
  EXPECT_DOUBLE_EQ(d.texel_probability(7, 1), 3.0 / 8.0);
  EXPECT_DOUBLE_EQ(d.texel_probability(4095, 2047), 4.0 / 8.0);
  EXPECT_EQ(d.texel_probability(1000000 % W, 1000000 / W), 0.0);
  EXPECT_EQ(d.texel_probability(6, 0), 0.0);
  EXPECT_EQ(d.pdf(Vec2((6 + 0.5) / W, 0.5 / H)), 0.0);
  std::mt19937_64 rng(3);
  std::array<int, 3> counts{};
  for (int i = 0; i < 80000; ++i) {
    const DistributionSample s = d.sample(Vec2(uniform53(rng), uniform53(rng)));
    const std::uint64_t t = std::uint64_t(s.y) * W + std::uint64_t(s.x);
    const auto k = std::find(texels.begin(), texels.end(), t) - texels.begin();
    ASSERT_TRUE(k == 0 || k == 1 || k == 3) << "drew texel " << t;
    ++counts[k == 3 ? 2 : std::size_t(k)];
    ASSERT_EQ(s.pdf, d.pdf(s.uv));
  }
  EXPECT_NEAR(counts[0] / 80000.0, 1.0 / 8.0, 0.006);
  EXPECT_NEAR(counts[1] / 80000.0, 3.0 / 8.0, 0.006);
  EXPECT_NEAR(counts[2] / 80000.0, 4.0 / 8.0, 0.006);
}

TEST(SparseDistribution2D, RefusesWhatIsNotASparseTable) {
  const std::vector<float> one = {1.0f}, two = {1.0f, 1.0f};
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{16}, one), Error);    // outside the grid
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{3, 3}, two), Error);  // repeated
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{5, 2}, two), Error);  // out of order
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{1, 2}, one), Error);  // sizes differ
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{}, std::vector<float>{}), Error);
  EXPECT_THROW(SparseDistribution2D(4, 4, std::vector<std::uint64_t>{1}, std::vector<float>{-1.0f}), Error);
  EXPECT_THROW(SparseDistribution2D(0, 4, std::vector<std::uint64_t>{1}, one), Error);
}

TEST(SparseDistribution2D, BlobRoundTripSamplesBitForBitAndChecksValues) {
  const SparseDistribution2D d(64, 32, std::vector<std::uint64_t>{10, 200, 1500},
                               std::vector<float>{0.5f, 2.0f, 1e-7f});
  BlobWriter w;
  d.save(w);
  std::vector<std::byte> blob = w.flatten();
  BlobReader r(blob.data(), blob.size(), "test blob");
  const SparseDistribution2D back(r);
  std::mt19937_64 rng(11);
  for (int i = 0; i < 1000; ++i) {
    const Vec2 u(uniform53(rng), uniform53(rng));
    const DistributionSample a = d.sample(u), b = back.sample(u);
    ASSERT_EQ(a.uv.x, b.uv.x);
    ASSERT_EQ(a.uv.y, b.uv.y);
    ASSERT_EQ(a.pdf, b.pdf);
  }
  // A density that disagrees with its cumulative step (the last stored value is the last texel's density).
  double v = 0.0;
  std::memcpy(&v, blob.data() + blob.size() - sizeof v, sizeof v);
  v *= 2.0;
  std::memcpy(blob.data() + blob.size() - sizeof v, &v, sizeof v);
  BlobReader bad(blob.data(), blob.size(), "patched blob");
  try {
    SparseDistribution2D{bad};
    FAIL() << "a patched cumulative step was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("patched blob"), std::string::npos) << e.what();
  }
}
