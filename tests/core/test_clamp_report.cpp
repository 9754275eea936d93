// count_clamped (clamp_report.h): blocks whose values all fit are passed over by a loop without branches, the rest
// counted value by value. Checked against a value-by-value count on images large enough for many blocks and
// parallel ranges, with values beyond the range, negatives, -0, NaN and Inf scattered at random.
#include <envkit/core/clamp_report.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <vector>

using envkit::ClampReport;
using envkit::FormatRange;

namespace {

ClampReport reference(const std::vector<float>& pixels, int channels, int used, const FormatRange& range) {
  ClampReport r;
  r.format = range.name;
  r.format_max = range.max[0];
  for (std::size_t t = 0; t < pixels.size() / std::size_t(channels); ++t)
    for (int c = 0; c < used; ++c) {
      const double v = pixels[t * std::size_t(channels) + std::size_t(c)];
      if (!std::isfinite(v)) continue;
      const double magnitude = range.is_signed ? std::abs(v) : v;
      if (magnitude > range.max[std::min(c, 2)]) {
        ++r.above;
        r.largest = std::max(r.largest, magnitude);
      } else if (!range.is_signed && v < 0.0) {
        ++r.negative;
        r.lowest = std::min(r.lowest, v);
      }
    }
  return r;
}

/// Values in [0, 100) with, one in `rarity` each, a value beyond 65504 (either sign), a negative, -0, NaN or +/-Inf.
std::vector<float> values(std::size_t n, unsigned seed, int rarity) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(0.0f, 100.0f), big(7e4f, 1e9f);
  std::uniform_int_distribution<int> kind(0, 6 * rarity - 1);
  std::vector<float> v(n);
  for (float& x : v) {
    x = value(rng);
    switch (kind(rng)) {
      case 0:
        x = big(rng);
        break;
      case 1:
        x = -big(rng);
        break;
      case 2:
        x = -value(rng) - 1.0f;
        break;
      case 3:
        x = -0.0f;
        break;
      case 4:
        x = std::numeric_limits<float>::quiet_NaN();
        break;
      case 5:
        x = (x > 50.0f ? 1.0f : -1.0f) * std::numeric_limits<float>::infinity();
        break;
      default:
        break;
    }
  }
  return v;
}

void expect_same(const ClampReport& got, const ClampReport& want, const char* what) {
  EXPECT_EQ(got.format, want.format) << what;
  EXPECT_EQ(got.above, want.above) << what;
  EXPECT_EQ(got.largest, want.largest) << what;
  EXPECT_EQ(got.negative, want.negative) << what;
  EXPECT_EQ(got.lowest, want.lowest) << what;
}

}  // namespace

TEST(CountClamped, MatchesAValueByValueCount) {
  static constexpr FormatRange kUnsigned{"rgbe", {3.0e38, 3.0e38, 3.0e38}, false};
  static constexpr FormatRange kSmall{"rg11b10f", {65024.0, 65024.0, 64512.0}, false};
  // 333,333 texels: many 1024-texel blocks and parallel ranges, and a ragged end. Rare specials leave most blocks
  // clean (the fast path), frequent ones reach every block.
  for (const int rarity : {20000, 50}) {
    for (const int channels : {3, 4}) {
      const std::vector<float> v = values(std::size_t(333333) * channels, unsigned(rarity + channels), rarity);
      for (const int used : {channels, 3}) {
        for (const FormatRange* range : {&envkit::kHalfRange, &kUnsigned, &kSmall}) {
          const ClampReport want = reference(v, channels, used, *range);
          ASSERT_GT(want.above + want.negative, 0u);
          expect_same(envkit::count_clamped(v, channels, used, *range), want, range->name);
        }
      }
    }
  }
  // Nothing to count: the fast path alone, and a report with nothing in it.
  const std::vector<float> clean(3 * 5000, 1.5f);
  const ClampReport none = envkit::count_clamped(clean, 3, 3, envkit::kHalfRange);
  EXPECT_FALSE(none.any());
  EXPECT_EQ(none.format, "half");
}
