// Tests of the marginal/conditional CDF distributions (distribution_cdf.h) and of the chi-square support (chi2.h).
#include <envkit/sampling/distribution_cdf.h>
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
  return h;
}

// Chi-square tests run by this executable: one per standard map + the two 1D tests below.
const int kChi2Tests = int(testmaps::standard_maps().size()) + 2;
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

// The float resolution of a CDF: each stored entry is at most 1/2 (two-sided), so it is rounded by at most
// 2^-25, and a step by 2^-24, in the marginal and in the conditional. A texel of marginal m and conditional c is
// drawn with probability within (m + c) 2^-24 of m c. (Relative to a tiny texel that can be large: the price of
// float CDFs; pdf() follows the stored steps, so estimators stay consistent.)
auto cdf_tolerance(const TestMap& map) {
  std::vector<double> row(std::size_t(map.height), 0.0);
  double total = 0.0;
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x)
      row[std::size_t(y)] +=
          sampling::sanitize_weight(map.weights[std::size_t(y) * std::size_t(map.width) + std::size_t(x)]);
    total += row[std::size_t(y)];
  }
  return [row, total](int, int y, double ideal) {
    if (!(total > 0.0)) return 1e-6 * ideal;  // uniform fallback: steps of 1/n, exact to float rounding
    const double m = row[std::size_t(y)] / total, c = m > 0.0 ? ideal / m : 0.0;
    return 1.01 * (m + c) * 0x1p-24 + 1e-12 * ideal;
  };
}

std::unique_ptr<CdfDistribution2D> build(const TestMap& m) {
  return std::make_unique<CdfDistribution2D>(m.weights.data(), m.width, m.height);
}

}  // namespace

// ------------------------------------------------------------------------------------------------------------
// chi2.h itself

TEST(Chi2Support, IncompleteGammaMatchesClosedForms) {
  for (double x : {1e-3, 0.1, 1.0, 2.5, 5.0, 30.0, 200.0}) {
    EXPECT_NEAR(chi2::regularized_gamma_q(1.0, x), std::exp(-x), 1e-13 * std::max(1.0, std::exp(-x))) << x;
    EXPECT_NEAR(chi2::regularized_gamma_p(0.5, x), std::erf(std::sqrt(x)), 1e-13) << x;
  }
  // Even dof: Q(n, x) = e^-x sum_{i<n} x^i / i! (the Poisson tail), summed in log space for large n.
  for (int n : {3, 50, 500}) {
    for (double x : {0.5 * n, 1.0 * n, 1.3 * n}) {
      double sum = 0.0;
      for (int i = 0; i < n; ++i) sum += std::exp(-x + i * std::log(x) - std::lgamma(i + 1.0));
      EXPECT_NEAR(chi2::regularized_gamma_q(n, x), sum, 1e-10 * std::max(sum, 1e-3)) << n << " " << x;
    }
  }
  EXPECT_NEAR(chi2::p_value(23.209251, 10), 0.01, 1e-6);  // chi-square table value
  EXPECT_EQ(chi2::p_value(5.0, 0), 1.0);
  EXPECT_NEAR(chi2::sidak_alpha(0.01, 1), 0.01, 1e-15);
  EXPECT_NEAR(chi2::sidak_alpha(0.01, 10), 0.00100453, 1e-8);
}

TEST(Chi2Support, PoolsSmallCellsAndFailsOnZeroCells) {
  // 20 cells expecting 1 each (pooled into 4 bins of 5) + 2 cells expecting 50.
  std::vector<double> expected(20, 1.0), observed(20, 1.0);
  expected.insert(expected.end(), {50.0, 50.0});
  observed.insert(observed.end(), {50.0, 50.0});
  chi2::Result r = chi2::test(observed, expected, 0.01);
  EXPECT_TRUE(r.passed) << r.message;
  EXPECT_EQ(r.pooled_cells, 20);
  EXPECT_EQ(r.dof, 4 + 2 - 1);
  EXPECT_NEAR(r.statistic, 0.0, 1e-12);
  // One sample in a cell of expected count 0 fails, whatever the p-value.
  expected.push_back(0.0);
  observed.push_back(1.0);
  r = chi2::test(observed, expected, 0.01);
  EXPECT_FALSE(r.passed);
  EXPECT_EQ(r.zero_cell_samples, 1.0);
}

TEST(Chi2Support, DetectsASlightlyWrongDistribution) {
  // Sample map A, test against map B = A with one texel 10% brighter: must fail.
  const TestMap a = testmaps::find_map("Odd7x3");
  const CdfDistribution2D dist(a.weights.data(), a.width, a.height);
  TestMap b = a;
  b.weights[10] *= 1.1f;
  EXPECT_TRUE(testmaps::chi_square(dist, a, kAlpha, 1).passed);
  const chi2::Result r = testmaps::chi_square(dist, b, kAlpha, 1);
  EXPECT_FALSE(r.passed) << r.message;
}

// The defect the GUIDE warns about, as a negative control: a marginal/conditional sampler whose CDFs are float
// running sums (pdf from the weights) loses the tail of the sun's row. The chi-square test must catch it.
TEST(Chi2Support, CatchesFloatRunningSumCdf) {
  const TestMap m = testmaps::find_map("SunRowTail2048x4");
  const auto float_cdf = [](const float* w, int n) {
    std::vector<float> cdf(std::size_t(n) + 1, 0.0f);
    for (int i = 0; i < n; ++i) cdf[std::size_t(i) + 1] = cdf[std::size_t(i)] + w[i];  // float accumulation
    for (float& c : cdf) c /= cdf.back();
    return cdf;
  };
  std::vector<std::vector<float>> rows;
  std::vector<float> row_sums;
  for (int y = 0; y < m.height; ++y) {
    const float* w = m.weights.data() + std::size_t(y) * std::size_t(m.width);
    float s = 0.0f;
    for (int x = 0; x < m.width; ++x) s += w[x];
    row_sums.push_back(s);
    rows.push_back(float_cdf(w, m.width));
  }
  const std::vector<float> marginal = float_cdf(row_sums.data(), m.height);
  const auto pick = [](const std::vector<float>& cdf, double u) {
    const int i = int(std::upper_bound(cdf.begin(), cdf.end(), float(u)) - cdf.begin()) - 1;
    const int n = int(cdf.size()) - 1;
    const double f = (u - cdf[std::size_t(i)]) / (cdf[std::size_t(i) + 1] - cdf[std::size_t(i)]);
    return (std::min(i, n - 1) + std::clamp(f, 0.0, 0.999)) / n;
  };
  std::mt19937_64 rng(7);
  const testmaps::Histogram h = testmaps::histogram(m.cells_x, m.cells_y, m.samples, [&] {
    const double v = pick(marginal, testmaps::uniform53(rng));
    const int y = std::min(int(v * m.height), m.height - 1);
    return Vec2(pick(rows[std::size_t(y)], testmaps::uniform53(rng)), v);
  });
  const std::vector<double> e = testmaps::expected_counts(testmaps::reference_probabilities(m.weights), m.width,
                                                          m.height, m.cells_x, m.cells_y, double(m.samples));
  const chi2::Result r = chi2::test(h.counts, e, kAlpha);
  EXPECT_FALSE(r.passed) << r.message;
  // ... while the two-sided double-accumulated CDF passes the same map.
  EXPECT_TRUE(testmaps::chi_square(*build(m), m, kAlpha, 7).passed);
}

// ------------------------------------------------------------------------------------------------------------
// CdfDistribution2D on the standard maps

class CdfMaps : public ::testing::TestWithParam<TestMap> {};

TEST_P(CdfMaps, ChiSquare) {
  const TestMap& m = GetParam();
  const chi2::Result r = testmaps::chi_square(*build(m), m, kAlpha, seed_of(m.name));
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
}

TEST_P(CdfMaps, PdfIntegratesToOne) { EXPECT_EQ(testmaps::check_normalised(*build(GetParam())), ""); }

TEST_P(CdfMaps, PdfMatchesWeights) {
  // pdf is the stored step product (exactly what is drawn); it is w / integral up to the CDF's float resolution.
  const TestMap& m = GetParam();
  EXPECT_EQ(testmaps::check_matches_weights(*build(m), m, cdf_tolerance(m), 1e-12), "");
}

TEST_P(CdfMaps, SamplesAreConsistent) {
  EXPECT_EQ(testmaps::check_samples(*build(GetParam()), GetParam(), 20000, seed_of(GetParam().name) + 1), "");
}

TEST_P(CdfMaps, InvertRoundTrips) {
  EXPECT_EQ(testmaps::check_invert(*build(GetParam()), 20000, seed_of(GetParam().name) + 2), "");
}

// sample_texel() and pick() are sample() before uv is formed (see testmaps::check_sample_texel).
TEST_P(CdfMaps, SampleTexelIsSampleBeforeUv) {
  EXPECT_EQ(testmaps::check_sample_texel(*build(GetParam()), GetParam().width, GetParam().height), "");
}

TEST_P(CdfMaps, PdfIsZeroOutside) { EXPECT_EQ(testmaps::check_pdf_outside(*build(GetParam())), ""); }

TEST_P(CdfMaps, ReportsFallbacks) {
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
  // Unreachable = positive weight but zero drawn probability (LogUniform's 1e-4 texels among 1e4 ones).
  std::size_t unreachable = 0;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      unreachable +=
          m.weights[std::size_t(y) * std::size_t(m.width) + std::size_t(x)] > 0.0f && d->texel_probability(x, y) == 0.0;
  EXPECT_EQ(d->unreachable_texels(), unreachable);
  if (m.name != "LogUniform48x24") {
    EXPECT_EQ(unreachable, 0u);
  }
  EXPECT_EQ(d->width(), m.width);
  EXPECT_EQ(d->height(), m.height);
  EXPECT_GT(d->bytes(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Maps, CdfMaps, ::testing::ValuesIn(testmaps::standard_maps()), testmaps::MapName());

// ------------------------------------------------------------------------------------------------------------
// Properties specific to the CDF

TEST(CdfDistribution2D, ConstantMapIsTheIdentityWarp) {
  const std::vector<float> w(16 * 8, 0.7f);
  const CdfDistribution2D d(w.data(), 16, 8);
  std::mt19937_64 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
    const DistributionSample s = d.sample(u);
    EXPECT_NEAR(s.uv.x, u.x, 1e-6);
    EXPECT_NEAR(s.uv.y, u.y, 1e-6);
    EXPECT_NEAR(s.pdf, 1.0, 1e-6);
  }
  EXPECT_NEAR(d.integral(), 0.7, 1e-7);
}

TEST(CdfDistribution2D, ResolvesTheSkyAfterASunInItsRow) {
  // Row: floor 1e-3, sun 1e6 in the middle. Each floor texel is 1e-9 of the row: with a plain float CDF every
  // texel after the sun would get a step of 0 or 2^-24. Two-sided storage resolves it.
  const int W = 4096;
  std::vector<float> w(W, 1e-3f);
  w[1000] = 1e6f;
  const CdfDistribution2D d(w.data(), W, 1);
  double sum = 0.0;
  for (float v : w) sum += v;
  double worst = 0.0;
  for (int x = 0; x < W; ++x) {
    const double ideal = w[std::size_t(x)] / sum, drawn = d.texel_probability(x, 0);
    ASSERT_GT(drawn, 0.0) << x;
    worst = std::max(worst, std::abs(drawn - ideal) / ideal);
  }
  EXPECT_LT(worst, 2.0 * W * 0x1p-24);  // ~2e-4 here: up to 3000 floor bins on the short side
  EXPECT_EQ(d.unreachable_texels(), 0u);
  // What a plain (one-sided) float CDF of the same row would store: most texels after the sun get no step.
  double prefix = 0.0;
  int zero_steps = 0;
  float previous = 0.0f;
  for (int x = 0; x < W; ++x) {
    prefix += w[std::size_t(x)];
    const float c = float(prefix / sum);
    zero_steps += c == previous;
    previous = c;
  }
  EXPECT_GT(zero_steps, 2000);
}

TEST(CdfDistribution2D, DimTexelBetweenTwoSunsIsCountedAndConsistent) {
  // The remaining limit of a float CDF: a texel below 2^-24 of the mass on BOTH sides. It gets a zero step;
  // pdf() must say 0 as well, and the count must report it.
  const std::vector<float> w = {1e6f, 1e-3f, 1e6f, 1.0f};
  const CdfDistribution2D d(w.data(), 4, 1);
  EXPECT_EQ(d.unreachable_texels(), 1u);
  EXPECT_EQ(d.texel_probability(1, 0), 0.0);
  EXPECT_EQ(d.pdf(Vec2(1.5 / 4, 0.5)), 0.0);
  EXPECT_GT(d.texel_probability(3, 0), 0.0);
  std::mt19937_64 rng(5);
  for (int i = 0; i < 100000; ++i) EXPECT_NE(d.sample(Vec2(testmaps::uniform53(rng), 0.5)).x, 1);
}

TEST(CdfDistribution2D, AllZeroRowsAreUniformForInvert) {
  std::vector<float> w(4 * 3, 1.0f);
  for (int x = 0; x < 4; ++x) w[4 + std::size_t(x)] = 0.0f;  // row 1 is dark
  const CdfDistribution2D d(w.data(), 4, 3);
  EXPECT_EQ(d.uniform_fallback_rows(), 1);
  EXPECT_FALSE(d.used_uniform_fallback());
  EXPECT_EQ(d.pdf(Vec2(0.3, 0.5)), 0.0);
  // Inside the dark row invert() follows the uniform conditional in x.
  EXPECT_NEAR(d.invert(Vec2(0.3, 0.5)).x, 0.3, 1e-6);
}

TEST(CdfDistribution2D, InfiniteAndHugeWeightsStayFinite) {
  std::vector<float> w(8 * 4, 1.0f);
  w[5] = std::numeric_limits<float>::infinity();
  w[6] = FLT_MAX;
  const CdfDistribution2D d(w.data(), 8, 4);
  EXPECT_TRUE(std::isfinite(d.integral()));
  EXPECT_EQ(testmaps::check_normalised(d), "");
  const DistributionSample s = d.sample(Vec2(0.3, 0.3));
  EXPECT_TRUE(std::isfinite(s.pdf));
  EXPECT_TRUE(s.x == 5 || s.x == 6);
}

TEST(CdfDistribution2D, RejectsBadSizes) {
  const float w = 1.0f;
  EXPECT_THROW(CdfDistribution2D(&w, 0, 1), Error);
  EXPECT_THROW(CdfDistribution2D(&w, 1, -1), Error);
  EXPECT_THROW(CdfDistribution2D(nullptr, 1, 1), Error);
}

// A loaded CDF table is checked before use: a split index of 0 (the forward part holds at least cdf[0] = 0) or
// past the end is refused with an error naming the blob, not searched out of bounds.
TEST(CdfDistribution2D, LoadRefusesSplitIndicesOutOfRange) {
  const std::vector<float> w = {1, 2, 3, 4, 5, 6, 0, 1, 9, 2, 2, 2};
  const CdfDistribution2D built(w.data(), 4, 3);
  BlobWriter writer;
  built.save(writer);
  const std::vector<std::byte> good = writer.flatten();
  BlobReader reader(good.data(), good.size(), "t.envtbl: section cdf");
  const CdfDistribution2D loaded(reader);
  EXPECT_EQ(loaded.sample(Vec2(0.3, 0.7)).uv, built.sample(Vec2(0.3, 0.7)).uv);
  for (std::int32_t bad : {0, -1, 4}) {  // the marginal split is the blob's last 8-byte word
    std::vector<std::byte> blob = good;
    std::memcpy(blob.data() + blob.size() - 8, &bad, sizeof bad);
    BlobReader in(blob.data(), blob.size(), "t.envtbl: section cdf");
    try {
      CdfDistribution2D d(in);
      ADD_FAILURE() << "split " << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("t.envtbl: section cdf"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("split"), std::string::npos) << e.what();
    }
  }
}

// The search sends every u < 1/2 to the forward part, so a table whose split leaves more than half the mass behind
// it would send some u past the forward part's last entry into the junction bin, whatever that bin's step (a zero
// step: a drawn sample with pdf 0, as fuzz_table_values found; a small one: samples in the wrong bin). Such a table
// rises, falls and sums to 1 like a valid one, and must be refused all the same.
TEST(CdfDistribution2D, LoadRefusesASplitWithMoreThanHalfTheMassBehindIt) {
  const std::vector<float> w = {1, 2, 3, 4, 5, 6, 0, 1, 9, 2, 2, 2};  // row sums 10, 12, 15: marginal split 2
  const CdfDistribution2D built(w.data(), 4, 3);
  BlobWriter writer;
  built.save(writer);
  const std::vector<std::byte> good = writer.flatten();
  // The marginal t = {0, 10/37 (forward), 15/37 (backward, at the split), 0}: find its middle entries.
  const float t1 = float(10.0 / 37.0), t2 = float(15.0 / 37.0);
  std::size_t at = 0;
  for (std::size_t k = 0; k + 8 <= good.size(); k += 4)
    if (std::memcmp(good.data() + k, &t1, 4) == 0 && std::memcmp(good.data() + k + 4, &t2, 4) == 0) at = k + 4;
  ASSERT_NE(at, 0u) << "marginal not found in the blob";
  // 0.7 at the split: rising forward part {0, 0.27}, falling backward part {0.7, 0}, junction step 0.03 >= 0.
  std::vector<std::byte> blob = good;
  const float behind = 0.7f;
  std::memcpy(blob.data() + at, &behind, sizeof behind);
  BlobReader in(blob.data(), blob.size(), "t.envtbl: section cdf");
  try {
    CdfDistribution2D d(in);
    ADD_FAILURE() << "a split with 0.7 of the mass behind it was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("t.envtbl: section cdf: invalid marginal CDF"), std::string::npos) << e.what();
  }
  // At exactly one half it is a table a build can write (a remaining mass just below 1/2 rounds to it): accepted.
  const float half = 0.5f;
  std::vector<std::byte> edge = good;
  std::memcpy(edge.data() + at, &half, sizeof half);
  BlobReader edge_in(edge.data(), edge.size(), "t.envtbl: section cdf");
  EXPECT_NO_THROW(CdfDistribution2D d(edge_in));
}

TEST(CdfDistribution2D, DeterministicAcrossThreadCounts) {
  const int W = 1024, H = 512;  // above the parallel threshold
  std::vector<float> w(std::size_t(W) * H);
  std::mt19937_64 rng(11);
  for (float& v : w) v = float(std::pow(10.0, 6.0 * testmaps::uniform53(rng) - 3.0));
  std::unique_ptr<CdfDistribution2D> one, many;
  tbb::task_arena(1).execute([&] { one = std::make_unique<CdfDistribution2D>(w.data(), W, H); });
  tbb::task_arena(2).execute([&] { many = std::make_unique<CdfDistribution2D>(w.data(), W, H); });
  for (int i = 0; i < 20000; ++i) {
    const Vec2 u(testmaps::uniform53(rng), testmaps::uniform53(rng));
    const DistributionSample a = one->sample(u), b = many->sample(u);
    ASSERT_EQ(std::memcmp(&a.uv, &b.uv, sizeof(Vec2)), 0);
    ASSERT_EQ(std::memcmp(&a.pdf, &b.pdf, sizeof(double)), 0);
  }
  EXPECT_EQ(one->integral(), many->integral());
}

// ------------------------------------------------------------------------------------------------------------
// PiecewiseConstant1D

TEST(PiecewiseConstant1D, ChiSquareAndInvert) {
  std::vector<float> w = {0.0f, 3.0f, 1.0f, 0.0f, 0.0f, 2.0f, 1e-4f, 5.0f, 0.5f};
  const PiecewiseConstant1D d(w);
  const int n = int(w.size()), cells = 27;
  std::mt19937_64 rng(13);
  const std::size_t samples = 500000;
  const testmaps::Histogram h = testmaps::histogram(cells, 1, samples, [&] {
    const auto s = d.sample(testmaps::uniform53(rng));
    EXPECT_GT(w[std::size_t(s.index)], 0.0f);
    EXPECT_DOUBLE_EQ(s.pdf, d.pdf(s.x));
    return Vec2(s.x, 0.5);
  });
  const std::vector<double> e =
      testmaps::expected_counts(testmaps::reference_probabilities(w), n, 1, cells, 1, double(samples));
  const chi2::Result r = chi2::test(h.counts, e, kAlpha);
  EXPECT_TRUE(r.passed) << r.message;
  for (int i = 0; i < 10000; ++i) {
    const double u = testmaps::uniform53(rng);
    EXPECT_NEAR(d.invert(d.sample(u).x), u, 1e-9);
  }
  double total = 0.0;
  for (int i = 0; i < n; ++i) total += d.bin_probability(i);
  EXPECT_NEAR(total, 1.0, 1e-7);
  EXPECT_NEAR(d.integral(), 11.5001 / 9, 1e-6);
  EXPECT_EQ(d.pdf(-0.1), 0.0);
  EXPECT_EQ(d.pdf(std::numeric_limits<double>::quiet_NaN()), 0.0);
}

TEST(PiecewiseConstant1D, AllZeroIsUniform) {
  const std::vector<float> w(5, 0.0f);
  const PiecewiseConstant1D d(w);
  EXPECT_TRUE(d.used_uniform_fallback());
  std::mt19937_64 rng(17);
  const std::size_t samples = 200000;
  const testmaps::Histogram h = testmaps::histogram(10, 1, samples, [&] {
    const auto s = d.sample(testmaps::uniform53(rng));
    EXPECT_NEAR(s.pdf, 1.0, 1e-6);
    return Vec2(s.x, 0.5);
  });
  const std::vector<double> e(10, samples / 10.0);
  const chi2::Result r = chi2::test(h.counts, e, kAlpha);
  EXPECT_TRUE(r.passed) << r.message;
}
