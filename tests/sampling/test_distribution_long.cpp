// Float-precision stress of the 2D distributions at 16384 x 8192 (134 M texels): a dim 1e-3 map with one 1e6 sun
// and a few texels of 1e-8 of the total in the places where float tables fail (right after the sun in its row, at
// the end of the sun's row, in the last row). Every method must give them, and every floor texel of the sun's
// row (1e-9 of that row), a non-zero probability equal to w / sum within the float bound of its tables.
// Slow and memory-hungry (~0.5 GB weights + up to 1.6 GB of tables, 5-20 s per test): meant for ctest label
// "long", not the default suite.
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <memory>

#include "chi2.h"

using namespace envkit;

namespace {

constexpr int kW = 16384, kH = 8192;
constexpr int kSunX = 9000, kSunY = 3000;
constexpr float kFloor = 1e-3f, kSun = 1e6f;

/// The stress map, with its exact row sums and total (double) for reference probabilities.
struct StressMap {
  std::vector<float> weights;
  std::vector<double> row_sum;
  double total = 0.0;
  std::vector<std::pair<int, int>> tiny;  // texels of weight 1e-8 x total

  float at(int x, int y) const { return weights[std::size_t(y) * kW + std::size_t(x)]; }
  double ideal(int x, int y) const { return at(x, y) / total; }
};

const StressMap& stress_map() {
  static const StressMap map = [] {
    StressMap m;
    m.weights.assign(std::size_t(kW) * kH, kFloor);
    m.weights[std::size_t(kSunY) * kW + kSunX] = kSun;
    const double approx_total = double(kFloor) * kW * kH + kSun;
    m.tiny = {{kSunX + 1, kSunY}, {kW - 1, kSunY}, {100, kSunY}, {kSunX, kSunY + 1}, {kW - 1, kH - 1}, {0, 0}};
    for (auto [x, y] : m.tiny) m.weights[std::size_t(y) * kW + std::size_t(x)] = float(1e-8 * approx_total);
    m.row_sum.assign(kH, 0.0);
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) m.row_sum[std::size_t(y)] += m.at(x, y);
      m.total += m.row_sum[std::size_t(y)];
    }
    return m;
  }();
  return map;
}

template <class Dist>
std::unique_ptr<Dist> timed_build(const StressMap& m) {
  const auto t0 = std::chrono::steady_clock::now();
  auto d = std::make_unique<Dist>(m.weights.data(), kW, kH);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[ info     ] " << d->method() << " 16384x8192: build " << seconds << " s, "
            << double(d->bytes()) / (double(kW) * kH) << " bytes/texel\n";
  return d;
}

/// The texels checked one by one: the tiny ones, the whole sun row, the sun's column, and a spread of others.
std::vector<std::pair<int, int>> checked_texels(const StressMap& m, int sun_row_step) {
  std::vector<std::pair<int, int>> t = m.tiny;
  for (int x = 0; x < kW; x += sun_row_step) t.emplace_back(x, kSunY);
  for (int x = kSunX - 64; x <= kSunX + 64; ++x) t.emplace_back(x, kSunY);
  for (int y = 0; y < kH; y += 7) t.emplace_back(kSunX, y);
  std::mt19937_64 rng(1);
  for (int i = 0; i < 20000; ++i) t.emplace_back(int(rng() % kW), int(rng() % kH));
  return t;
}

/// Samples are consistent at this size too: inside their texel, pdf(uv) == sample.pdf, never NaN.
void check_some_samples(const Distribution2D& d) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 200000; ++i) {
    const DistributionSample s = d.sample(Vec2(testmaps::uniform53(rng), testmaps::uniform53(rng)));
    ASSERT_EQ(sampling::texel_index(s.uv.x, kW), s.x);
    ASSERT_EQ(sampling::texel_index(s.uv.y, kH), s.y);
    ASSERT_TRUE(s.pdf > 0.0 && std::isfinite(s.pdf));
    ASSERT_EQ(d.pdf(s.uv), s.pdf);
  }
}

/// sample(invert(centre of texel)) must land in the texel: it is reachable with 53-bit u.
void check_reachable(const Distribution2D& d, int x, int y) {
  const DistributionSample s = d.sample(d.invert(Vec2((x + 0.5) / kW, (y + 0.5) / kH)));
  EXPECT_EQ(s.x, x) << "texel (" << x << "," << y << ")";
  EXPECT_EQ(s.y, y) << "texel (" << x << "," << y << ")";
}

}  // namespace

TEST(DistributionLong, Cdf16kTinyTexelsKeepTheirProbability) {
  const StressMap& m = stress_map();
  const auto d = timed_build<CdfDistribution2D>(m);
  EXPECT_EQ(d->unreachable_texels(), 0u);  // every one of the 134 M positive texels has a non-zero step
  EXPECT_NEAR(d->integral() * double(kW) * kH, m.total, 1e-9 * m.total);

  // Bound of a two-sided float CDF: each entry v (at most 1/2: the mass on its smaller side) is rounded by at
  // most 2^-24 v, so a step by 2^-24 (v_lo + v_hi). Prefix masses from double sums.
  std::vector<double> row_prefix(kH + 1, 0.0);
  for (int y = 0; y < kH; ++y) row_prefix[std::size_t(y) + 1] = row_prefix[std::size_t(y)] + m.row_sum[std::size_t(y)];
  const auto side = [](double prefix, double total) { return std::min(prefix / total, 1.0 - prefix / total); };
  std::vector<double> sun_row_prefix(kW + 1, 0.0);
  for (int x = 0; x < kW; ++x) sun_row_prefix[std::size_t(x) + 1] = sun_row_prefix[std::size_t(x)] + m.at(x, kSunY);
  const auto prefix_in_row = [&](int x, int y) {
    if (y == kSunY) return sun_row_prefix[std::size_t(x)];
    double p = 0.0;
    for (int i = 0; i < x; ++i) p += m.at(i, y);
    return p;
  };

  double worst_relative = 0.0;
  for (auto [x, y] : checked_texels(m, 1)) {
    const double ideal = m.ideal(x, y), drawn = d->texel_probability(x, y);
    ASSERT_GT(drawn, 0.0) << x << "," << y;
    const double rs = m.row_sum[std::size_t(y)], mm = rs / m.total, c = ideal / mm;
    const double dm =
        0x1p-24 * (side(row_prefix[std::size_t(y)], m.total) + side(row_prefix[std::size_t(y) + 1], m.total));
    const double prefix_lo = prefix_in_row(x, y), prefix_hi = prefix_lo + m.at(x, y);
    const double dc = 0x1p-24 * (side(prefix_lo, rs) + side(prefix_hi, rs));
    ASSERT_LE(std::abs(drawn - ideal), 1.01 * (mm * dc + c * dm + dm * dc) + 1e-12 * ideal)
        << "texel (" << x << "," << y << "): drawn " << drawn << ", ideal " << ideal;
    worst_relative = std::max(worst_relative, std::abs(drawn - ideal) / ideal);
  }
  std::cout << "[ info     ] cdf: worst relative probability error of the checked texels " << worst_relative << "\n";
  for (auto [x, y] : m.tiny) check_reachable(*d, x, y);
  check_some_samples(*d);

  // The negative control: a plain (one-sided) float CDF of the sun's row, even accumulated in double, gives most
  // floor texels after the sun a zero step; accumulated in float, it stops growing after the sun altogether.
  int zero_steps_double = 0, zero_steps_float = 0;
  float previous = 0.0f, running = 0.0f, previous_running = 0.0f;
  for (int x = 0; x < kW; ++x) {
    const float c = float(sun_row_prefix[std::size_t(x) + 1] / sun_row_prefix[kW]);
    zero_steps_double += c == previous;
    previous = c;
    running += m.at(x, kSunY);
    zero_steps_float += running == previous_running;
    previous_running = running;
  }
  EXPECT_GT(zero_steps_double, 5000);
  EXPECT_GE(zero_steps_float, kW - kSunX - 1);
}

TEST(DistributionLong, Alias16kTinyTexelsKeepTheirProbability) {
  const StressMap& m = stress_map();
  const auto d = timed_build<AliasDistribution2D>(m);
  EXPECT_NEAR(d->integral() * double(kW) * kH, m.total, 1e-9 * m.total);
  // texel_probability is O(W + H) for alias: check the tiny texels, every 16th texel of the sun's row, the sun's
  // neighbourhood and 200 random texels.
  std::vector<std::pair<int, int>> texels = m.tiny;
  for (int x = 0; x < kW; x += 16) texels.emplace_back(x, kSunY);
  for (int x = kSunX - 64; x <= kSunX + 64; ++x) texels.emplace_back(x, kSunY);
  std::mt19937_64 rng(2);
  for (int i = 0; i < 200; ++i) texels.emplace_back(int(rng() % kW), int(rng() % kH));
  double worst_relative = 0.0;
  for (auto [x, y] : texels) {
    const double ideal = m.ideal(x, y), drawn = d->texel_probability(x, y);
    ASSERT_GT(drawn, 0.0) << x << "," << y;
    ASSERT_NEAR(drawn, ideal, 1e-6 * ideal) << "texel (" << x << "," << y << ")";
    ASSERT_NEAR(d->pdf(Vec2((x + 0.5) / kW, (y + 0.5) / kH)) / (double(kW) * kH), ideal, 1e-9 * ideal);
    worst_relative = std::max(worst_relative, std::abs(drawn - ideal) / ideal);
  }
  std::cout << "[ info     ] alias: worst relative probability error of the checked texels " << worst_relative << "\n";
  check_some_samples(*d);
}

TEST(DistributionLong, Hierarchical16kTinyTexelsKeepTheirProbability) {
  const StressMap& m = stress_map();
  const auto d = timed_build<HierarchicalDistribution2D>(m);
  EXPECT_EQ(d->levels(), 14);
  EXPECT_NEAR(d->integral() * double(kW) * kH, m.total, 1e-9 * m.total);
  double worst_relative = 0.0;
  for (auto [x, y] : checked_texels(m, 1)) {
    const double ideal = m.ideal(x, y), drawn = d->texel_probability(x, y);
    ASSERT_GT(drawn, 0.0) << x << "," << y;
    ASSERT_NEAR(drawn, ideal, 5e-6 * ideal) << "texel (" << x << "," << y << ")";  // <= 28 float ratios
    ASSERT_NEAR(d->pdf(Vec2((x + 0.5) / kW, (y + 0.5) / kH)) / (double(kW) * kH), ideal, 1e-9 * ideal);
    worst_relative = std::max(worst_relative, std::abs(drawn - ideal) / ideal);
  }
  std::cout << "[ info     ] pyramid: worst relative probability error of the checked texels " << worst_relative
            << "\n";
  for (auto [x, y] : m.tiny) check_reachable(*d, x, y);
  check_some_samples(*d);
}
