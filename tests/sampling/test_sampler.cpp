// The Owen-scrambled Sobol sampler: every power-of-two prefix of a pixel's samples is a (0, 2)-net in each
// dimension pair (the stratification the hierarchical warp keeps), values stay in [0, 1), and points depend only on
// the seed, the pixel and the sample index.
#include <envkit/sampling/sampler.h>
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>
#include <vector>

using namespace envkit;

namespace {

std::vector<Vec2> points(std::uint32_t seed, int px, int py, int dimension_pair, int n) {
  OwenSobolSampler s(seed, px, py);
  std::vector<Vec2> p;
  for (int i = 0; i < n; ++i) {
    s.start_sample(std::uint32_t(i));
    Vec2 v(0.0, 0.0);
    for (int d = 0; d <= dimension_pair; ++d) v = s.next_2d();
    p.push_back(v);
  }
  return p;
}

}  // namespace

TEST(OwenSobolSampler, EveryPowerOfTwoPrefixIsA02Net) {
  // A (0, m, 2)-net in base 2: every elementary interval of area 2^-m (2^k x 2^(m-k) cells) holds exactly one point.
  for (const auto& [px, py] : {std::pair{0, 0}, std::pair{17, 3}, std::pair{1023, 511}})
    for (const int pair : {0, 1, 2, 7}) {
      const std::vector<Vec2> p = points(5u, px, py, pair, 1 << 10);
      for (const int m : {1, 4, 7, 10}) {
        const int n = 1 << m;
        for (int k = 0; k <= m; ++k) {
          const int cx = 1 << k, cy = 1 << (m - k);
          std::set<long> cells;
          for (int i = 0; i < n; ++i) cells.insert(long(std::floor(p[i].x * cx)) * cy + long(std::floor(p[i].y * cy)));
          EXPECT_EQ(int(cells.size()), n) << "pixel " << px << "," << py << " pair " << pair << ": first " << n
                                          << " points in " << cx << " x " << cy << " cells";
        }
      }
    }
}

TEST(OwenSobolSampler, ValuesLieInTheUnitSquareAndDependOnlyOnSeedPixelAndIndex) {
  const std::vector<Vec2> a = points(9u, 4, 5, 3, 4096), b = points(9u, 4, 5, 3, 4096);
  const std::vector<Vec2> other_pixel = points(9u, 5, 4, 3, 4096), other_seed = points(10u, 4, 5, 3, 4096);
  int same_pixel = 0, same_seed = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].x, b[i].x);
    EXPECT_EQ(a[i].y, b[i].y);
    EXPECT_GE(a[i].x, 0.0);
    EXPECT_LT(a[i].x, 1.0);
    EXPECT_GE(a[i].y, 0.0);
    EXPECT_LT(a[i].y, 1.0);
    same_pixel += a[i].x == other_pixel[i].x;
    same_seed += a[i].x == other_seed[i].x;
  }
  EXPECT_EQ(same_pixel, 0);
  EXPECT_EQ(same_seed, 0);
}

TEST(OwenSobolSampler, DimensionPairsAreDecorrelated) {
  // The x of pair 0 and the x of pair 1 over 4096 samples: correlation near 0 (shuffled indices per pair).
  const std::vector<Vec2> p0 = points(3u, 8, 8, 0, 4096), p1 = points(3u, 8, 8, 1, 4096);
  double sa = 0, sb = 0, sab = 0, saa = 0, sbb = 0;
  for (std::size_t i = 0; i < p0.size(); ++i) {
    sa += p0[i].x;
    sb += p1[i].x;
    sab += p0[i].x * p1[i].x;
    saa += p0[i].x * p0[i].x;
    sbb += p1[i].x * p1[i].x;
  }
  const double n = double(p0.size());
  const double cov = sab / n - sa / n * sb / n;
  const double corr = cov / std::sqrt((saa / n - sa / n * sa / n) * (sbb / n - sb / n * sb / n));
  EXPECT_LT(std::abs(corr), 0.06);  // 4 standard errors of an uncorrelated pair at n = 4096
}

// point_2d: the m points of each of a pixel's samples are together one sequence. With m = 4 points per sample,
// the first n samples' 4n points are a (0, 2)-net, as 4n samples of next_2d() are; the pair is consumed once.
TEST(OwenSobolSampler, SeveralPointsPerSampleAreOneStratifiedSequence) {
  constexpr std::uint32_t m = 4;
  OwenSobolSampler s(5u, 17, 3);
  std::vector<Vec2> p;
  for (std::uint32_t i = 0; i < 256; ++i) {
    s.start_sample(i);
    s.next_2d();  // another pair before: the group's own pair is whichever reserve() returns
    const std::uint32_t d = s.reserve(1);
    for (std::uint32_t k = 0; k < m; ++k) p.push_back(s.point_2d(d, k, m));
    EXPECT_EQ(s.reserve(0), d + 1);  // one pair for the whole group
    EXPECT_EQ(s.point_1d(d, 0, m), p[i * m].x);
  }
  for (const int n : {4, 64, 1024}) {
    const int bits = int(std::log2(n));
    for (int k = 0; k <= bits; ++k) {
      const int cx = 1 << k, cy = 1 << (bits - k);
      std::set<long> cells;
      for (int i = 0; i < n; ++i) cells.insert(long(std::floor(p[i].x * cx)) * cy + long(std::floor(p[i].y * cy)));
      EXPECT_EQ(int(cells.size()), n) << "first " << n << " points in " << cx << " x " << cy << " cells";
    }
  }
  // A group of one point is next_2d().
  OwenSobolSampler a(8u, 1, 2), b(8u, 1, 2);
  a.start_sample(9);
  b.start_sample(9);
  const Vec2 u = a.next_2d(), v = b.point_2d(b.reserve(1), 0, 1);
  EXPECT_EQ(u.x, v.x);
  EXPECT_EQ(u.y, v.y);
}
