#pragma once
/// @file chi2.h
/// Statistical test support for envkit's sampling code (header-only).
///
/// 1. envkit::chi2: Pearson's chi-square goodness-of-fit test in the style of Nori's warptest and Mitsuba's chi2
///    module. The caller supplies observed and expected counts over any set of cells (uv cells, cells on the
///    sphere, ...). Cells are sorted by expected count; cells with expected count < 5 are pooled in that order;
///    any sample in a cell whose expected count is 0 fails the test outright; the p-value comes from the
///    regularised upper incomplete gamma function Q(dof/2, chi2/2), implemented here (series / Lentz continued
///    fraction, Numerical Recipes style). Use sidak_alpha() to correct the significance level for the number of
///    tests in a run.
/// 2. envkit::testmaps: helpers for distributions on the uv square: the reference texel probabilities of a weight
///    grid, exact expected counts over a grid of cells, the standard catalogue of test maps, and property checks
///    shared by the distribution tests (each returns an empty string on success, else what went wrong).
#include <envkit/sampling/distribution.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <numeric>
#include <random>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace envkit::chi2 {

/// Regularised lower incomplete gamma function P(a, x) = gamma(a, x) / Gamma(a), a > 0, x >= 0.
double regularized_gamma_p(double a, double x);

/// Regularised upper incomplete gamma function Q(a, x) = 1 - P(a, x), computed directly where the continued
/// fraction converges (x >= a + 1) so that small p-values keep their relative precision.
double regularized_gamma_q(double a, double x);

namespace detail {
// Series for P(a, x), converges quickly for x < a + 1.
inline double gamma_p_series(double a, double x) {
  double ap = a, term = 1.0 / a, sum = term;
  for (int n = 0; n < 100000; ++n) {
    ap += 1.0;
    term *= x / ap;
    sum += term;
    if (std::abs(term) < std::abs(sum) * 1e-16) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}
// Continued fraction for Q(a, x) (modified Lentz), converges quickly for x >= a + 1.
inline double gamma_q_continued_fraction(double a, double x) {
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}
}  // namespace detail

inline double regularized_gamma_p(double a, double x) {
  if (!(a > 0.0) || !(x > 0.0)) return 0.0;
  if (x < a + 1.0) return detail::gamma_p_series(a, x);
  return 1.0 - detail::gamma_q_continued_fraction(a, x);
}

inline double regularized_gamma_q(double a, double x) {
  if (!(a > 0.0) || !(x > 0.0)) return 1.0;
  if (x < a + 1.0) return 1.0 - detail::gamma_p_series(a, x);
  return detail::gamma_q_continued_fraction(a, x);
}

/// P(X >= statistic) for X chi-square distributed with dof degrees of freedom.
inline double p_value(double statistic, int dof) {
  return dof > 0 ? regularized_gamma_q(0.5 * dof, 0.5 * statistic) : 1.0;
}

/// Per-test significance level so that `tests` independent tests together reject a correct implementation with
/// probability alpha: 1 - (1 - alpha)^(1/tests).
inline double sidak_alpha(double alpha, int tests) { return 1.0 - std::pow(1.0 - alpha, 1.0 / std::max(1, tests)); }

struct Result {
  bool passed = false;
  double statistic = 0.0;
  int dof = 0;
  double p_value = 1.0;
  double alpha = 0.0;
  int cells = 0;                 ///< cells with a positive expected count
  int pooled_cells = 0;          ///< of which pooled (expected < min_expected)
  double zero_cell_samples = 0;  ///< samples in cells whose expected count is 0 (any -> failure)
  std::string message;           ///< one line summary; says why on failure
};

/// Chi-square test of observed against expected counts over the same cells (any layout; sums should agree:
/// expected = N x the probability of each cell under the pdf being tested).
inline Result test(std::span<const double> observed, std::span<const double> expected, double alpha,
                   double min_expected = 5.0) {
  Result r;
  r.alpha = alpha;
  std::vector<std::size_t> order(expected.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return expected[a] < expected[b]; });

  double pool_observed = 0.0, pool_expected = 0.0;
  int bins = 0;
  const auto add_bin = [&](double o, double e) {
    r.statistic += (o - e) * (o - e) / e;
    ++bins;
  };
  for (std::size_t index : order) {
    const double e = expected[index], o = observed[index];
    if (!(e > 0.0)) {
      r.zero_cell_samples += o;
      continue;
    }
    ++r.cells;
    if (e < min_expected || pool_expected > 0.0) {
      // Small cells are pooled in ascending order until the pool reaches min_expected.
      pool_observed += o;
      pool_expected += e;
      r.pooled_cells += e < min_expected;
      if (pool_expected >= min_expected) {
        add_bin(pool_observed, pool_expected);
        pool_observed = pool_expected = 0.0;
      }
    } else {
      add_bin(o, e);
    }
  }
  // A pool still below min_expected at the end (every cell was small): count it as one bin anyway.
  if (pool_expected > 0.0) add_bin(pool_observed, pool_expected);

  r.dof = bins - 1;
  r.p_value = p_value(r.statistic, r.dof);
  std::ostringstream msg;
  msg << "chi2 = " << r.statistic << ", dof = " << r.dof << ", p = " << r.p_value << " (alpha " << alpha << ", "
      << r.cells << " cells, " << r.pooled_cells << " pooled)";
  if (r.zero_cell_samples > 0) {
    msg << "; FAIL: " << r.zero_cell_samples << " samples in cells of expected count 0";
    r.passed = false;
  } else if (!(r.p_value >= alpha)) {  // NaN fails too
    msg << "; FAIL: p-value below alpha";
    r.passed = false;
  } else {
    r.passed = true;
  }
  r.message = msg.str();
  return r;
}

}  // namespace envkit::chi2

namespace envkit::testmaps {

/// A uniform double in [0,1) with 53 random bits.
inline double uniform53(std::mt19937_64& rng) { return double(rng() >> 11) * 0x1p-53; }

/// A stable seed per test map (FNV-1a of its name), varied per test file by `salt`.
inline std::uint64_t seed_of(const std::string& name, std::uint64_t salt) {
  std::uint64_t h = 1469598103934665603ull;
  for (char c : name) h = (h ^ std::uint8_t(c)) * 1099511628211ull;
  return h ^ salt;
}

/// The ideal texel probabilities of a weight grid: w / sum(w) with the tables' sanitising (negative/NaN -> 0,
/// inf -> FLT_MAX), uniform when every weight is zero (the documented fallback). Accumulated in double.
inline std::vector<double> reference_probabilities(std::span<const float> weights) {
  std::vector<double> p(weights.size());
  double sum = 0.0;
  for (std::size_t i = 0; i < weights.size(); ++i) sum += p[i] = sampling::sanitize_weight(weights[i]);
  for (double& v : p) v = sum > 0.0 ? v / sum : 1.0 / double(p.size());
  return p;
}

/// Expected counts of n samples over cols x rows equal cells of [0,1)^2 for a density that is constant on each of
/// the W x H texels with the given probabilities. Exact: texel/cell overlaps are computed in integers.
inline std::vector<double> expected_counts(std::span<const double> texel_probability, int W, int H, int cols, int rows,
                                           double n) {
  std::vector<double> e(std::size_t(cols) * std::size_t(rows), 0.0);
  // In units of 1/(W cols): texel x spans [x cols, (x+1) cols), cell c spans [c W, (c+1) W).
  const auto overlaps = [](int texel, int texels, int cells, auto&& fn) {
    const long long t0 = (long long)texel * cells, t1 = t0 + cells;
    for (long long c = t0 / texels; c * texels < t1 && c < cells; ++c) {
      const long long o = std::min(t1, (c + 1) * texels) - std::max(t0, c * (long long)texels);
      if (o > 0) fn(int(c), double(o) / double(cells));  // fraction of the texel inside the cell
    }
  };
  for (int y = 0; y < H; ++y)
    overlaps(y, H, rows, [&](int r, double fy) {
      for (int x = 0; x < W; ++x) {
        const double p = texel_probability[std::size_t(y) * std::size_t(W) + std::size_t(x)];
        if (p == 0.0) continue;
        overlaps(x, W, cols,
                 [&](int c, double fx) { e[std::size_t(r) * std::size_t(cols) + std::size_t(c)] += n * p * fx * fy; });
      }
    });
  return e;
}

struct Histogram {
  std::vector<double> counts;
  std::size_t outside = 0;  ///< samples outside [0,1)^2 or NaN
};

/// Bins n points uv = draw(rng) into cols x rows cells of [0,1)^2.
template <class Draw>
Histogram histogram(int cols, int rows, std::size_t n, Draw&& draw) {
  Histogram h;
  h.counts.assign(std::size_t(cols) * std::size_t(rows), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 uv = draw();
    if (!(uv.x >= 0.0 && uv.x < 1.0 && uv.y >= 0.0 && uv.y < 1.0)) {
      ++h.outside;
      continue;
    }
    const int c = std::min(int(uv.x * cols), cols - 1), r = std::min(int(uv.y * rows), rows - 1);
    h.counts[std::size_t(r) * std::size_t(cols) + std::size_t(c)] += 1.0;
  }
  return h;
}

/// A named weight grid plus the cell grid and sample count its chi-square test uses.
struct TestMap {
  std::string name;  ///< a valid gtest parameter name
  int width = 0, height = 0;
  std::vector<float> weights;
  int cells_x = 0, cells_y = 0;
  std::size_t samples = 1000000;
};

inline TestMap make_map(std::string name, int w, int h, int cells_x, int cells_y) {
  TestMap m;
  m.name = std::move(name);
  m.width = w;
  m.height = h;
  m.weights.assign(std::size_t(w) * std::size_t(h), 0.0f);
  m.cells_x = cells_x;
  m.cells_y = cells_y;
  return m;
}

/// The maps every distribution is tested on: constant, one bright texel, 3x2, light only in the first and last
/// rows, a 1e6 peak over a 1e-3 floor, all-zero rows, 1x1, odd sizes, 2:1 lat-long, non-power-of-two, an
/// all-zero map (uniform fallback), 1-texel-wide strips, log-uniform weights over 8 decades, a checkerboard of
/// zeros, and invalid weights (negative, NaN, inf).
inline std::vector<TestMap> standard_maps() {
  std::vector<TestMap> maps;
  std::mt19937_64 rng(20240601);
  const auto rnd = [&](double lo, double hi) { return float(lo + (hi - lo) * uniform53(rng)); };
  const auto fill_random = [&](TestMap& m, double lo, double hi) {
    for (float& w : m.weights) w = rnd(lo, hi);
  };
  const auto at = [](TestMap& m, int x, int y) -> float& {
    return m.weights[std::size_t(y) * std::size_t(m.width) + std::size_t(x)];
  };

  {  // Cells finer than texels: tests uniformity inside texels.
    TestMap m = make_map("Constant8x4", 8, 4, 24, 12);
    std::fill(m.weights.begin(), m.weights.end(), 1.0f);
    maps.push_back(m);
  }
  {
    TestMap m = make_map("OneBrightTexel16x16", 16, 16, 32, 32);
    at(m, 5, 11) = 3.0f;
    maps.push_back(m);
  }
  {
    TestMap m = make_map("Map3x2", 3, 2, 9, 8);
    m.weights = {0.5f, 2.0f, 0.0f, 4.0f, 1.0f, 7.0f};
    maps.push_back(m);
  }
  {
    TestMap m = make_map("FirstAndLastRows16x8", 16, 8, 32, 16);
    for (int x = 0; x < 16; ++x) {
      at(m, x, 0) = rnd(0.5, 1.5);
      at(m, x, 7) = rnd(0.5, 1.5);
    }
    maps.push_back(m);
  }
  {  // Dynamic range 1e9. The floor is big enough (32k texels) that 2M samples put ~65 in it, so a sampler that
     // loses or over-weights the floor (float CDF steps after the peak) fails.
    TestMap m = make_map("Peak1e6Floor1e3_256x128", 256, 128, 64, 32);
    std::fill(m.weights.begin(), m.weights.end(), 1e-3f);
    at(m, 200, 77) = 1e6f;
    m.samples = 2000000;
    maps.push_back(m);
  }
  {  // Light after the sun in the sun's own row: 0.02 is below half an ulp of 1e6 in float, so a float running
     // sum drops the whole tail of row 1 (~82 of 2M samples expected there); a plain float CDF rounds its steps.
    TestMap m = make_map("SunRowTail2048x4", 2048, 4, 16, 4);
    std::fill(m.weights.begin(), m.weights.end(), 0.02f);
    at(m, 5, 1) = 1e6f;
    m.samples = 2000000;
    maps.push_back(m);
  }
  {
    TestMap m = make_map("ZeroRows32x16", 32, 16, 32, 16);
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 32; ++x) at(m, x, y) = (y == 0 || y == 1 || y == 7 || y == 15) ? 0.0f : rnd(0.0, 1.0);
    maps.push_back(m);
  }
  {
    TestMap m = make_map("Single1x1", 1, 1, 8, 8);
    m.weights = {2.5f};
    maps.push_back(m);
  }
  {
    TestMap m = make_map("Odd7x3", 7, 3, 14, 9);
    fill_random(m, 0.0, 1.0);
    maps.push_back(m);
  }
  {
    TestMap m = make_map("Odd33x17", 33, 17, 33, 17);
    fill_random(m, 0.0, 1.0);
    maps.push_back(m);
  }
  {  // Lat-long-like 2:1: sky gradient x sin(theta) plus a small sun.
    TestMap m = make_map("LatLong64x32", 64, 32, 64, 32);
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 64; ++x) {
        const double theta = kPi * (y + 0.5) / 32, sky = 0.2 + std::max(0.0, std::cos(theta));
        double w = sky * std::sin(theta);
        if (std::abs(x - 40) <= 1 && std::abs(y - 9) <= 1) w += 500.0;
        at(m, x, y) = float(w);
      }
    maps.push_back(m);
  }
  {
    TestMap m = make_map("NonPow2_100x37", 100, 37, 50, 37);
    for (float& w : m.weights) w = uniform53(rng) < 0.2 ? 0.0f : rnd(0.0, 2.0);
    maps.push_back(m);
  }
  maps.push_back(make_map("AllZero5x3", 5, 3, 10, 6));
  {
    TestMap m = make_map("Strip1x9", 1, 9, 4, 18);
    fill_random(m, 0.0, 1.0);
    maps.push_back(m);
  }
  {
    TestMap m = make_map("Strip13x1", 13, 1, 26, 4);
    fill_random(m, 0.0, 1.0);
    maps.push_back(m);
  }
  {
    TestMap m = make_map("LogUniform48x24", 48, 24, 48, 24);
    for (float& w : m.weights) w = float(std::pow(10.0, rnd(-4.0, 4.0)));
    maps.push_back(m);
  }
  {  // Zero texels inside every 2x2 block.
    TestMap m = make_map("Checker20x10", 20, 10, 40, 20);
    for (int y = 0; y < 10; ++y)
      for (int x = 0; x < 20; ++x) at(m, x, y) = (x + y) % 2 ? 0.0f : rnd(0.5, 1.0);
    maps.push_back(m);
  }
  {  // Negative, NaN, -0 and -inf weights are treated as 0.
    TestMap m = make_map("InvalidWeights6x5", 6, 5, 12, 10);
    fill_random(m, 0.0, 1.0);
    m.weights[3] = -1.0f;
    m.weights[7] = std::numeric_limits<float>::quiet_NaN();
    m.weights[12] = -0.0f;
    m.weights[20] = -std::numeric_limits<float>::infinity();
    maps.push_back(m);
  }
  return maps;
}

/// The standard maps that carry light (for distributions without a uniform fallback).
inline std::vector<TestMap> lit_standard_maps() {
  std::vector<TestMap> maps;
  for (TestMap& m : standard_maps()) {
    double total = 0.0;
    for (float w : m.weights) total += sampling::sanitize_weight(w);
    if (total > 0.0) maps.push_back(std::move(m));
  }
  return maps;
}

/// The standard map called `name` (throws if there is none).
inline TestMap find_map(const std::string& name) {
  for (TestMap& m : standard_maps())
    if (m.name == name) return m;
  throw std::runtime_error("no standard test map named " + name);
}

/// gtest parameter-name generator for TestMap parameters.
struct MapName {
  template <class Info>
  std::string operator()(const Info& info) const {
    return info.param.name;
  }
};

/// Chi-square test of dist against the map's ideal probabilities (w / sum, not dist.pdf(): the reference is
/// independent of the implementation). u is drawn from mt19937_64 with the given seed.
inline chi2::Result chi_square(const Distribution2D& dist, const TestMap& map, double alpha, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Histogram h = histogram(map.cells_x, map.cells_y, map.samples, [&] {
    const double ux = uniform53(rng), uy = uniform53(rng);
    return dist.sample(Vec2(ux, uy)).uv;
  });
  const std::vector<double> p = reference_probabilities(map.weights);
  const std::vector<double> e =
      expected_counts(p, map.width, map.height, map.cells_x, map.cells_y, double(map.samples));
  chi2::Result r = chi2::test(h.counts, e, alpha);
  if (h.outside > 0) {
    r.passed = false;
    r.message += "; FAIL: " + std::to_string(h.outside) + " samples outside [0,1)^2";
  }
  return r;
}

/// Sum over texels of pdf(texel centre) x texel area must be 1.
inline std::string check_normalised(const Distribution2D& dist, double tolerance = 1e-6) {
  double sum = 0.0;
  for (int y = 0; y < dist.height(); ++y)
    for (int x = 0; x < dist.width(); ++x) sum += dist.pdf(Vec2((x + 0.5) / dist.width(), (y + 0.5) / dist.height()));
  sum /= double(dist.width()) * double(dist.height());
  if (std::abs(sum - 1.0) > tolerance) return "sum of pdf x area = " + std::to_string(sum);
  return {};
}

/// pdf at every texel centre equals the ideal w / integral: |pdf x area - ideal| <= tolerance(x, y, ideal)
/// (an absolute bound on the probability), and texel_probability() (what the tables draw) agrees with pdf x area
/// within a relative `consistency`.
template <class Tolerance>
std::string check_matches_weights(const Distribution2D& dist, const TestMap& map, const Tolerance& tolerance,
                                  double consistency = 1e-5) {
  const std::vector<double> p = reference_probabilities(map.weights);
  const double area = 1.0 / (double(map.width) * double(map.height));
  std::ostringstream err;
  int failures = 0;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const double ideal = p[std::size_t(y) * std::size_t(map.width) + std::size_t(x)];
      const double pdf = dist.pdf(Vec2((x + 0.5) / map.width, (y + 0.5) / map.height));
      const double drawn = dist.texel_probability(x, y);
      const bool ok = std::abs(pdf * area - ideal) <= tolerance(x, y, ideal) &&
                      std::abs(drawn - pdf * area) <= consistency * pdf * area;
      if (!ok && failures++ < 5)
        err << "texel (" << x << "," << y << "): ideal " << ideal << ", pdf x area " << pdf * area
            << ", texel_probability " << drawn << "; ";
    }
  return err.str();
}

/// The same with a relative tolerance on every texel.
inline std::string check_matches_weights(const Distribution2D& dist, const TestMap& map, double rel_tolerance) {
  return check_matches_weights(
      dist, map, [rel_tolerance](int, int, double ideal) { return rel_tolerance * ideal; }, rel_tolerance);
}

/// For n random u and a set of edge u: the sample is finite, inside [0,1)^2 and inside its texel (x, y); its texel
/// has positive ideal probability; sample.pdf == pdf(sample.uv) within 1e-12 relative (they share the formula).
inline std::string check_samples(const Distribution2D& dist, const TestMap& map, std::size_t n, std::uint64_t seed) {
  const std::vector<double> p = reference_probabilities(map.weights);
  std::vector<Vec2> us;
  const double edges[] = {0.0,
                          0x1p-60,
                          0.5,
                          0x1.fffffep-1,
                          kOneMinusEpsilon,
                          1.0,
                          -0.25,
                          1.5,
                          std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity()};
  for (double a : edges)
    for (double b : edges) us.emplace_back(a, b);
  std::mt19937_64 rng(seed);
  for (std::size_t i = 0; i < n; ++i) us.emplace_back(uniform53(rng), uniform53(rng));
  std::ostringstream err;
  int failures = 0;
  for (const Vec2& u : us) {
    const DistributionSample s = dist.sample(u);
    std::string why;
    if (!(s.uv.x >= 0.0 && s.uv.x < 1.0 && s.uv.y >= 0.0 && s.uv.y < 1.0))
      why = "uv outside [0,1)";
    else if (s.x < 0 || s.x >= map.width || s.y < 0 || s.y >= map.height)
      why = "texel index out of range";
    else if (sampling::texel_index(s.uv.x, map.width) != s.x || sampling::texel_index(s.uv.y, map.height) != s.y)
      why = "uv not inside texel (x, y)";
    else if (!(p[std::size_t(s.y) * std::size_t(map.width) + std::size_t(s.x)] > 0.0))
      why = "zero-weight texel";
    else if (!(s.pdf > 0.0) || !std::isfinite(s.pdf))
      why = "pdf not positive and finite";
    else if (std::abs(dist.pdf(s.uv) - s.pdf) > 1e-12 * s.pdf)
      why = "pdf(uv) != sample.pdf";
    if (!why.empty() && failures++ < 5)
      err << why << " at u = (" << u.x << ", " << u.y << "): uv = (" << s.uv.x << ", " << s.uv.y << "), texel (" << s.x
          << "," << s.y << "), pdf " << s.pdf << "; ";
  }
  return err.str();
}

/// invert(sample(u).uv) == u within tolerance for n random u, and invert() of any uv (edges, NaN) is finite in
/// [0,1).
inline std::string check_invert(const Distribution2D& dist, std::size_t n, std::uint64_t seed,
                                double tolerance = 1e-4) {
  std::ostringstream err;
  int failures = 0;
  std::mt19937_64 rng(seed);
  double worst = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 u(uniform53(rng), uniform53(rng));
    const Vec2 back = dist.invert(dist.sample(u).uv);
    const double d = std::max(std::abs(back.x - u.x), std::abs(back.y - u.y));
    worst = std::max(worst, d);
    if (!(d <= tolerance) && failures++ < 5)
      err << "u = (" << u.x << ", " << u.y << ") -> (" << back.x << ", " << back.y << "); ";
  }
  const double edges[] = {0.0, 0.5, 1.0, -1.0, 2.0, std::numeric_limits<double>::quiet_NaN()};
  for (double a : edges)
    for (double b : edges) {
      const Vec2 u = dist.invert(Vec2(a, b));
      if (!(u.x >= 0.0 && u.x < 1.0 && u.y >= 0.0 && u.y < 1.0) && failures++ < 5)
        err << "invert(" << a << ", " << b << ") = (" << u.x << ", " << u.y << "); ";
    }
  if (failures > 0) err << "worst round-trip error " << worst;
  return err.str();
}

/// sample_texel() and pick() (what SphericalDistribution uses) are sample() before uv is formed: same texel and
/// pdf, uv = ((x + fx) / W, (y + fy) / H) bit for bit, offsets in [0, kTexelOffsetMax]; also at the edges of u
/// and for NaN. D is a concrete distribution class (pick() is its inline, non-virtual texel choice).
template <class D>
std::string check_sample_texel(const D& dist, int width, int height, std::size_t n = 2000) {
  std::mt19937_64 rng(7);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec2 edges[] = {Vec2(0, 0),  Vec2(1, 1),     Vec2(kOneMinusEpsilon, 0),
                        Vec2(-1, 2), Vec2(nan, nan), Vec2(0.5, kOneMinusEpsilon)};
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 u = i < std::size(edges) ? edges[i] : Vec2(uniform53(rng), uniform53(rng));
    const DistributionSample s = dist.sample(u);
    const TexelSample t = dist.sample_texel(u), p = dist.pick(u);
    std::ostringstream at;
    at << " at u = (" << u.x << ", " << u.y << ")";
    if (std::memcmp(&t, &p, sizeof(TexelSample)) != 0) return "pick() differs from sample_texel()" + at.str();
    if (t.x != s.x || t.y != s.y || t.pdf != s.pdf) return "texel or pdf differs from sample()" + at.str();
    if (!(t.fx >= 0.0 && t.fx <= kTexelOffsetMax && t.fy >= 0.0 && t.fy <= kTexelOffsetMax))
      return "offset outside [0, kTexelOffsetMax]" + at.str();
    if ((t.x + t.fx) / width != s.uv.x || (t.y + t.fy) / height != s.uv.y)
      return "uv is not (texel + offset) / size" + at.str();
  }
  return {};
}

/// pdf() outside the closed unit square and for NaN is 0.
inline std::string check_pdf_outside(const Distribution2D& dist) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec2 outside[] = {{-0.01, 0.5}, {0.5, -1e-12}, {1.0001, 0.5}, {0.5, 2.0}, {nan, 0.5}, {0.5, nan}};
  for (const Vec2& uv : outside)
    if (dist.pdf(uv) != 0.0) return "pdf(" + std::to_string(uv.x) + ", " + std::to_string(uv.y) + ") != 0";
  for (const Vec2& uv : {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0.5, 1.0)})
    if (!std::isfinite(dist.pdf(uv)) || dist.pdf(uv) < 0.0) return "pdf on the boundary not finite";
  return {};
}

}  // namespace envkit::testmaps
