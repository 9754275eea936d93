// bench_precision: float vs double accumulation of sampling tables against the map size (a plain program, not a
// Google Benchmark one; it is built with the other bench_* programs).
//
//   bench_precision [--sizes 1024,2048,4096,8192,16384] [--samples 1000000] [--cells 64x32] [--seed S]
//
// Map: lat-long W x W/2, sky radiance 1e-3 everywhere plus a sun of radiance 1e6 on the texels whose centres lie
// within 1.5 texel heights (angular radius 1.5 pi / H) of (theta, phi) = (0.35 pi, 1.3 pi): ~8 texels at every
// size. Weights = radiance x exact texel solid angle ((2 pi / W)(cos theta0 - cos theta1)), stored as float,
// which is what the tables are built from.
// Reference: p_exact = w / sum(w), the sum accumulated in long double over the float weights.
// Methods:
//   float-naive  the textbook marginal/conditional CDF (as PBRT-v3's Distribution1D): per row a running float sum
//                cdf[i] = cdf[i-1] + f[i-1] / n, divided by the float total cdf[n]; the marginal likewise over
//                the rows' float totals. Texel probability = marginal step x conditional step (in double from the
//                stored floats).
//   cdf          envkit's CdfDistribution2D (double accumulation, two-sided float storage);
//                texel_probability() = what it samples.
//   hierarchical envkit's HierarchicalDistribution2D (double node sums, float storage); texel_probability().
// Per method: max and mean relative error |p - p_exact| / p_exact over the lit texels (all texels here), the
// number of lit texels with p = 0 (unreachable), the exact probability mass of those texels (lost mass), the
// total variation distance 0.5 sum |p - p_exact|, the relative error of the method's total, and a chi-square
// test of S samples (53-bit u from mt19937_64) on a coarse cell grid against the exact per-cell sums of p_exact
// (tests/chi2.h: cells of expected count < 5 pooled; any sample in a zero-expectation cell fails).
// Output: '#' comment lines, then a tab-separated table with a header row (machine-readable), on stdout;
// progress on stderr.
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../chi2.h"

using namespace envkit;

namespace {

constexpr double kSky = 1e-3, kSun = 1e6, kSunRadiusTexels = 1.5;
constexpr double kSunTheta = 0.35 * kPi, kSunPhi = 1.3 * kPi;

struct Map {
  int W = 0, H = 0;
  std::vector<float> w;
  long double sum = 0.0L;
  std::size_t sun_texels = 0;
  double sun_share = 0.0;  // exact share of the sun in the total
};

Map make_map(int W) {
  Map m;
  m.W = W;
  m.H = W / 2;
  const int H = m.H;
  m.w.resize(std::size_t(W) * std::size_t(H));
  const double r = kSunRadiusTexels * kPi / H;
  long double sun = 0.0L;
  for (int y = 0; y < H; ++y) {
    const double t0 = kPi * y / H, t1 = kPi * (y + 1) / H, tc = kPi * (y + 0.5) / H;
    const double omega = (kTwoPi / W) * (std::cos(t0) - std::cos(t1));
    const float sky = float(kSky * omega);
    float* row = m.w.data() + std::size_t(y) * std::size_t(W);
    std::fill(row, row + W, sky);
    if (std::abs(tc - kSunTheta) > r) continue;
    for (int x = 0; x < W; ++x) {
      const double dt = tc - kSunTheta, dp = (kTwoPi * (x + 0.5) / W - kSunPhi) * std::sin(kSunTheta);
      if (dt * dt + dp * dp <= r * r) {
        row[x] = float((kSun + kSky) * omega);
        ++m.sun_texels;
      }
    }
  }
  for (int y = 0; y < H; ++y) {
    const float* row = m.w.data() + std::size_t(y) * std::size_t(W);
    for (int x = 0; x < W; ++x) {
      m.sum += row[x];
      if (row[x] > float(2.0 * kSky * kTwoPi / W * kPi / H)) sun += row[x];  // sun texels are far above any sky texel
    }
  }
  m.sun_share = double(sun / m.sum);
  return m;
}

/// The textbook float marginal/conditional CDF (PBRT-v3 Distribution1D, float running sums).
struct NaiveFloatCdf2D {
  int W = 0, H = 0;
  std::vector<float> conditional;  // H rows of W + 1
  std::vector<float> marginal;     // H + 1
  float total = 0.0f;              // the marginal's float integral x H (sum of row integrals)

  static float build_1d(const float* f, int n, float* cdf) {
    cdf[0] = 0.0f;
    for (int i = 1; i <= n; ++i) cdf[i] = cdf[i - 1] + f[i - 1] / float(n);
    const float integral = cdf[n];
    for (int i = 1; i <= n; ++i) cdf[i] = integral == 0.0f ? float(i) / float(n) : cdf[i] / integral;
    return integral;
  }

  NaiveFloatCdf2D(const std::vector<float>& w, int width, int height) : W(width), H(height) {
    conditional.resize(std::size_t(W + 1) * std::size_t(H));
    std::vector<float> row_integral(static_cast<std::size_t>(H));
    for (int y = 0; y < H; ++y)
      row_integral[std::size_t(y)] = build_1d(w.data() + std::size_t(y) * std::size_t(W), W,
                                              conditional.data() + std::size_t(y) * std::size_t(W + 1));
    marginal.resize(std::size_t(H) + 1);
    total = build_1d(row_integral.data(), H, marginal.data());
  }

  double texel_probability(int x, int y) const {
    const float* c = conditional.data() + std::size_t(y) * std::size_t(W + 1);
    return (double(marginal[std::size_t(y) + 1]) - double(marginal[std::size_t(y)])) *
           (double(c[x + 1]) - double(c[x]));
  }

  /// Texel drawn for u (continuous inversion: the bin i with cdf[i] <= u < cdf[i+1]).
  static int find(const float* cdf, int n, double u) {
    const float* it = std::upper_bound(cdf, cdf + n + 1, u, [](double a, float b) { return a < double(b); });
    return std::clamp(int(it - cdf) - 1, 0, n - 1);
  }
  void sample(double ux, double uy, int& x, int& y) const {
    y = find(marginal.data(), H, uy);
    x = find(conditional.data() + std::size_t(y) * std::size_t(W + 1), W, ux);
  }
};

struct Stats {
  double max_rel = 0.0, sum_rel = 0.0, lost_mass = 0.0, tv = 0.0, total_p = 0.0;
  std::size_t lit = 0, unreachable = 0;
};

Stats errors(const Map& m, const std::function<double(int, int)>& probability) {
  Stats s;
  const long double inv = 1.0L / m.sum;
  for (int y = 0; y < m.H; ++y)
    for (int x = 0; x < m.W; ++x) {
      const float w = m.w[std::size_t(y) * std::size_t(m.W) + std::size_t(x)];
      const double pe = double(w * inv);
      const double p = probability(x, y);
      s.total_p += p;
      if (!(w > 0.0f)) continue;
      ++s.lit;
      const double rel = std::abs(p - pe) / pe;
      s.max_rel = std::max(s.max_rel, rel);
      s.sum_rel += rel;
      s.tv += std::abs(p - pe);
      if (p == 0.0) {
        ++s.unreachable;
        s.lost_mass += pe;
      }
    }
  s.tv *= 0.5;
  return s;
}

struct Chi2Out {
  double p = 1.0;
  int dof = 0;
  double zero_cell_samples = 0.0;
};

Chi2Out chi_square(const Map& m, int cols, int rows, std::size_t samples, std::uint64_t seed,
                   const std::function<void(double, double, int&, int&)>& draw) {
  std::vector<long double> exact(std::size_t(cols) * std::size_t(rows), 0.0L);
  for (int y = 0; y < m.H; ++y) {
    const std::size_t r = std::size_t((long long)y * rows / m.H);
    for (int x = 0; x < m.W; ++x)
      exact[r * std::size_t(cols) + std::size_t((long long)x * cols / m.W)] +=
          m.w[std::size_t(y) * std::size_t(m.W) + std::size_t(x)];
  }
  std::vector<double> expected(exact.size()), observed(exact.size(), 0.0);
  for (std::size_t i = 0; i < exact.size(); ++i) expected[i] = double(exact[i] / m.sum * (long double)samples);
  std::mt19937_64 rng(seed);
  for (std::size_t i = 0; i < samples; ++i) {
    const double ux = testmaps::uniform53(rng), uy = testmaps::uniform53(rng);
    int x = 0, y = 0;
    draw(ux, uy, x, y);
    observed[std::size_t((long long)y * rows / m.H) * std::size_t(cols) + std::size_t((long long)x * cols / m.W)] +=
        1.0;
  }
  const chi2::Result r = chi2::test(observed, expected, 0.01);
  return {r.p_value, r.dof, r.zero_cell_samples};
}

std::vector<int> parse_list(const std::string& text) {
  std::vector<int> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) v.push_back(std::atoi(item.c_str()));
  return v;
}

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {1024, 2048, 4096, 8192, 16384};
  std::size_t samples = 1000000;
  int cols = 64, rows = 32;
  std::uint64_t seed = 20261123;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if (a == "--sizes" && has)
      sizes = parse_list(argv[++i]);
    else if (a == "--samples" && has)
      samples = std::size_t(std::atof(argv[++i]));
    else if (a == "--cells" && has) {
      if (std::sscanf(argv[++i], "%dx%d", &cols, &rows) != 2) return 2;
    } else if (a == "--seed" && has)
      seed = std::strtoull(argv[++i], nullptr, 10);
    else {
      std::fprintf(stderr, "usage: bench_precision [--sizes 1024,2048,...] [--samples N] [--cells 64x32] [--seed S]\n");
      return 2;
    }
  }
  for (int W : sizes)
    if (W < 2 * cols || W % (2 * rows) != 0 || W % cols != 0) {
      std::fprintf(stderr, "bench_precision: width %d must be a multiple of the cell grid\n", W);
      return 2;
    }

  std::printf(
      "# map: lat-long W x W/2, sky %g + sun %g (radius %.1f texel heights at theta %.2f pi, phi %.2f pi), "
      "weights = radiance x exact texel solid angle, float\n",
      kSky, kSun, kSunRadiusTexels, kSunTheta / kPi, kSunPhi / kPi);
  std::printf("# reference: w / sum(w) in long double; chi-square: %zu samples, %dx%d cells, exact cell sums\n",
              samples, cols, rows);
  std::printf(
      "width\theight\tsun_texels\tsun_share\tmethod\tmax_rel_err\tmean_rel_err\tunreachable\tlit_texels\t"
      "lost_mass\ttv_distance\ttotal_rel_err\tchi2_p\tchi2_dof\tchi2_zero_cell_samples\tbuild_s\n");
  std::fflush(stdout);

  for (int W : sizes) {
    auto t0 = std::chrono::steady_clock::now();
    const Map m = make_map(W);
    std::fprintf(stderr, "bench_precision: %dx%d map (%zu sun texels) in %.1f s\n", W, m.H, m.sun_texels, elapsed(t0));
    const auto row = [&](const char* method, const Stats& s, double total_rel, const Chi2Out& c, double build_s) {
      std::printf("%d\t%d\t%zu\t%.6g\t%s\t%.6g\t%.6g\t%zu\t%zu\t%.6g\t%.6g\t%.6g\t%.6g\t%d\t%.0f\t%.3f\n", W, m.H,
                  m.sun_texels, m.sun_share, method, s.max_rel, s.sum_rel / double(std::max<std::size_t>(s.lit, 1)),
                  s.unreachable, s.lit, s.lost_mass, s.tv, total_rel, c.p, c.dof, c.zero_cell_samples, build_s);
      std::fflush(stdout);
    };
    {
      t0 = std::chrono::steady_clock::now();
      const NaiveFloatCdf2D d(m.w, m.W, m.H);
      const double build_s = elapsed(t0);
      const Stats s = errors(m, [&](int x, int y) { return d.texel_probability(x, y); });
      // The float total is the marginal's integral: sum of row integrals (each sum(w)/W) divided by H.
      const double total_rel = double(std::abs((long double)d.total * m.W * m.H - m.sum) / m.sum);
      const Chi2Out c = chi_square(m, cols, rows, samples, seed,
                                   [&](double ux, double uy, int& x, int& y) { d.sample(ux, uy, x, y); });
      row("float-naive", s, total_rel, c, build_s);
    }
    {
      t0 = std::chrono::steady_clock::now();
      const CdfDistribution2D d(m.w.data(), m.W, m.H);
      const double build_s = elapsed(t0);
      const Stats s = errors(m, [&](int x, int y) { return d.texel_probability(x, y); });
      const double total_rel = double(std::abs((long double)d.integral() * m.W * m.H - m.sum) / m.sum);
      const Chi2Out c = chi_square(m, cols, rows, samples, seed, [&](double ux, double uy, int& x, int& y) {
        const DistributionSample ds = d.sample(Vec2(ux, uy));
        x = ds.x;
        y = ds.y;
      });
      if (d.unreachable_texels() != s.unreachable)
        std::fprintf(stderr, "bench_precision: note: cdf reports %zu unreachable texels, counted %zu\n",
                     d.unreachable_texels(), s.unreachable);
      row("cdf", s, total_rel, c, build_s);
    }
    {
      t0 = std::chrono::steady_clock::now();
      const HierarchicalDistribution2D d(m.w.data(), m.W, m.H);
      const double build_s = elapsed(t0);
      const Stats s = errors(m, [&](int x, int y) { return d.texel_probability(x, y); });
      const double total_rel = double(std::abs((long double)d.integral() * m.W * m.H - m.sum) / m.sum);
      const Chi2Out c = chi_square(m, cols, rows, samples, seed, [&](double ux, double uy, int& x, int& y) {
        const DistributionSample ds = d.sample(Vec2(ux, uy));
        x = ds.x;
        y = ds.y;
      });
      row("hierarchical", s, total_rel, c, build_s);
    }
    std::fprintf(stderr, "bench_precision: %dx%d done\n", W, m.H);
  }
  return 0;
}
