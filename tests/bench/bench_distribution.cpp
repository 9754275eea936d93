// Benchmarks of the 2D sampling distributions (cdf, alias, pyramid) on sky-plus-sun maps at 1024x512 and
// 8192x4096: build time, ns per sample / pdf / invert with independent random u, bytes per texel.
//   bench_distribution --benchmark_filter=sample   (etc.)
#include <benchmark/benchmark.h>
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace envkit;

namespace {

/// A lat-long-like importance map: a smooth sky (brighter towards the zenith and the horizon) times sin(theta),
/// plus a sun of ~0.5 degrees carrying ~90% of the energy.
const std::vector<float>& sky_map(int W, int H) {
  static std::map<std::pair<int, int>, std::vector<float>> cache;
  std::vector<float>& w = cache[{W, H}];
  if (!w.empty()) return w;
  w.resize(std::size_t(W) * std::size_t(H));
  const double sun_theta = 0.35 * kPi, sun_phi = 1.3 * kPi, sun_radius = 0.0045;
  double sky_total = 0.0;
  for (int y = 0; y < H; ++y) {
    const double theta = kPi * (y + 0.5) / H, s = std::sin(theta);
    for (int x = 0; x < W; ++x) {
      const double phi = kTwoPi * (x + 0.5) / W;
      const double sky = 0.3 + 0.7 * std::max(0.0, std::cos(theta)) + 0.2 * std::exp(-8.0 * std::abs(std::cos(theta))) +
                         0.05 * std::sin(3.0 * phi);
      w[std::size_t(y) * std::size_t(W) + std::size_t(x)] = float(sky * s);
      sky_total += sky * s;
    }
  }
  // The sun: a disc of angular radius sun_radius, uniform radiance, total 9 x the sky.
  std::vector<std::size_t> sun;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double dt = kPi * (y + 0.5) / H - sun_theta, dp = (kTwoPi * (x + 0.5) / W - sun_phi) * std::sin(sun_theta);
      if (dt * dt + dp * dp <= sun_radius * sun_radius) sun.push_back(std::size_t(y) * std::size_t(W) + std::size_t(x));
    }
  if (sun.empty()) sun.push_back(std::size_t(sun_theta / kPi * H) * std::size_t(W) + std::size_t(sun_phi / kTwoPi * W));
  for (std::size_t i : sun) w[i] += float(9.0 * sky_total / double(sun.size()));
  return w;
}

enum class Method { Cdf, Alias, Pyramid };
const char* name(Method m) { return m == Method::Cdf ? "cdf" : m == Method::Alias ? "alias" : "hierarchical"; }

std::unique_ptr<Distribution2D> make(Method m, const std::vector<float>& w, int W, int H) {
  switch (m) {
    case Method::Cdf:
      return std::make_unique<CdfDistribution2D>(w.data(), W, H);
    case Method::Alias:
      return std::make_unique<AliasDistribution2D>(w.data(), W, H);
    case Method::Pyramid:
      return std::make_unique<HierarchicalDistribution2D>(w.data(), W, H);
  }
  return nullptr;
}

/// One distribution per (method, size), built on first use and kept for the sampling benchmarks. The large ones
/// are released when the next size starts, so at most one size's tables are alive.
const Distribution2D& cached(Method m, int W, int H) {
  static std::map<std::tuple<int, int, int>, std::unique_ptr<Distribution2D>> cache;
  auto& d = cache[{int(m), W, H}];
  if (!d) {
    for (auto it = cache.begin(); it != cache.end();)
      it = (std::get<1>(it->first) != W && it->second) ? cache.erase(it) : std::next(it);
    d = make(m, sky_map(W, H), W, H);
  }
  return *cache[{int(m), W, H}];
}

/// xorshift64* with 53-bit doubles: cheap enough not to dominate the timings.
struct Rng {
  std::uint64_t s = 0x9e3779b97f4a7c15ull;
  double next() {
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    return double((s * 0x2545f4914f6cdd1dull) >> 11) * 0x1p-53;
  }
};

void bench_build(benchmark::State& state, Method m, int W, int H) {
  const std::vector<float>& w = sky_map(W, H);
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto d = make(m, w, W, H);
    bytes = d->bytes();
    benchmark::DoNotOptimize(d.get());
  }
  state.counters["bytes/texel"] = double(bytes) / (double(W) * double(H));
  state.counters["Mtexel/s"] =
      benchmark::Counter(double(W) * double(H) * 1e-6 * double(state.iterations()), benchmark::Counter::kIsRate);
}

void bench_sample(benchmark::State& state, Method m, int W, int H) {
  const Distribution2D& d = cached(m, W, H);
  Rng rng;
  for (auto _ : state) {
    const Vec2 u(rng.next(), rng.next());
    benchmark::DoNotOptimize(d.sample(u));
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["bytes/texel"] = double(d.bytes()) / (double(W) * double(H));
}

void bench_pdf(benchmark::State& state, Method m, int W, int H) {
  const Distribution2D& d = cached(m, W, H);
  Rng rng;
  for (auto _ : state) {
    const Vec2 uv(rng.next(), rng.next());
    benchmark::DoNotOptimize(d.pdf(uv));
  }
  state.SetItemsProcessed(state.iterations());
}

void bench_invert(benchmark::State& state, Method m, int W, int H) {
  const Distribution2D& d = cached(m, W, H);
  Rng rng;
  for (auto _ : state) {
    const Vec2 uv(rng.next(), rng.next());
    benchmark::DoNotOptimize(d.invert(uv));
  }
  state.SetItemsProcessed(state.iterations());
}

}  // namespace

int main(int argc, char** argv) {
  const std::pair<int, int> sizes[] = {{1024, 512}, {8192, 4096}};
  const Method methods[] = {Method::Cdf, Method::Alias, Method::Pyramid};
  // Grouped by size so that only one size's tables are alive at a time (8192x4096: ~0.5-1.6 GB per method).
  for (auto [W, H] : sizes) {
    const std::string size = std::to_string(W) + "x" + std::to_string(H);
    for (Method m : methods)
      benchmark::RegisterBenchmark(("build/" + std::string(name(m)) + "/" + size).c_str(), bench_build, m, W, H)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->MinTime(W > 2048 ? 0.01 : 0.5);  // large builds: a single iteration is a stable enough figure
    for (Method m : methods)
      benchmark::RegisterBenchmark(("sample/" + std::string(name(m)) + "/" + size).c_str(), bench_sample, m, W, H);
    for (Method m : methods)
      benchmark::RegisterBenchmark(("pdf/" + std::string(name(m)) + "/" + size).c_str(), bench_pdf, m, W, H);
    for (Method m : {Method::Cdf, Method::Pyramid})
      benchmark::RegisterBenchmark(("invert/" + std::string(name(m)) + "/" + size).c_str(), bench_invert, m, W, H);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
