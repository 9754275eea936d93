// Benchmarks of direction sampling from baked tables (env_sampling.h / env_tables.h) on a sky-plus-sun lat-long
// at 1024x512 and 8192x4096: ns per sample (u -> direction + pdf + texel) and per pdf(direction) for cdf,
// alias and hierarchical; the bake from an in-memory image; loading the same tables from a file.
//   bench_env_sampling --benchmark_filter=Sample      (Sample: one sample() per call; SampleBatch: batched)
//   bench_env_sampling --benchmark_filter='Bake|Load'
#include <benchmark/benchmark.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <span>

using namespace envkit;

namespace {

/// RGB sky (brighter towards the zenith) with a ~0.5 degree sun carrying ~90% of the power.
const EnvMap& sky(int W, int H) {
  static std::map<int, std::unique_ptr<EnvMap>> cache;
  auto& slot = cache[W];
  if (slot) return *slot;
  slot = std::make_unique<EnvMap>();
  EnvMap& env = *slot;
  env.param = std::make_unique<LatLongMap>(W, H);
  env.image = Image(W, H, 3);
  const Vec3 sun_dir = Vec3(0.4, 0.5, -0.7).normalized();
  const double cos_sun = std::cos(0.0045);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Vec3 d = LatLongMap::direction_from_uv((x + 0.5) / W, (y + 0.5) / H);
      const double sky_value = 0.3 + 0.7 * std::max(0.0, d.y);
      const bool in_sun = d.dot(sun_dir) >= cos_sun;
      float* p = env.image.at(x, y);
      p[0] = float(in_sun ? 4e5 : sky_value * 0.8);
      p[1] = float(in_sun ? 4e5 : sky_value * 0.9);
      p[2] = float(in_sun ? 4e5 : sky_value * 1.2);
    }
  return env;
}

const EnvTables& tables(int W) {
  static std::map<int, std::unique_ptr<EnvTables>> cache;
  auto& slot = cache[W];
  if (!slot) slot = std::make_unique<EnvTables>(EnvTables::bake(sky(W, W / 2), BakeOptions{}));
  return *slot;
}

std::vector<Vec2> random_u(std::size_t n) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<Vec2> u(n);
  for (auto& v : u) v = Vec2(U(rng), U(rng));
  return u;
}

void Sample(benchmark::State& state) {
  const int W = int(state.range(0));
  const SphericalDistribution& d = *tables(W).distribution(SamplingMethod(state.range(1)));
  const std::vector<Vec2> u = random_u(1 << 16);
  std::size_t i = 0;
  for (auto _ : state) {
    const DirectionSample s = d.sample(u[i++ & 0xffff]);
    benchmark::DoNotOptimize(s);
  }
  state.SetLabel(std::string(method_name(SamplingMethod(state.range(1)))) + " " + std::to_string(W) + "x" +
                 std::to_string(W / 2));
}

/// The batched sample() of the same u as Sample, 256 per call: the per-sample time is the counter per_sample.
void SampleBatch(benchmark::State& state) {
  const int W = int(state.range(0));
  const SphericalDistribution& d = *tables(W).distribution(SamplingMethod(state.range(1)));
  const std::vector<Vec2> u = random_u(1 << 16);
  constexpr std::size_t kCall = 256;
  std::vector<DirectionSample> out(kCall);
  std::size_t i = 0;
  for (auto _ : state) {
    d.sample(std::span<const Vec2>(u.data() + i, kCall), out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
    i = (i + kCall) & 0xffff;
  }
  state.counters["per_sample"] =
      benchmark::Counter(double(kCall), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.SetLabel(std::string(method_name(SamplingMethod(state.range(1)))) + " " + std::to_string(W) + "x" +
                 std::to_string(W / 2) + ", batched");
}

void Pdf(benchmark::State& state) {
  const int W = int(state.range(0));
  const SphericalDistribution& d = *tables(W).distribution(SamplingMethod(state.range(1)));
  std::vector<Vec3> dirs;
  for (const Vec2& u : random_u(1 << 16)) dirs.push_back(d.sample(u).direction);
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(d.pdf(dirs[i++ & 0xffff]));
  state.SetLabel(std::string(method_name(SamplingMethod(state.range(1)))) + " " + std::to_string(W) + "x" +
                 std::to_string(W / 2));
}

void Bake(benchmark::State& state) {
  const int W = int(state.range(0));
  const EnvMap& env = sky(W, W / 2);
  const std::string hash = image_content_hash(env.image);  // the bake's own hashing is not what we time
  for (auto _ : state) {
    EnvTables t = EnvTables::bake(env, BakeOptions{}, "", hash);
    benchmark::DoNotOptimize(t);
  }
  state.SetLabel("importance + cdf + alias + hierarchical, " + std::to_string(W) + "x" + std::to_string(W / 2));
}

void Load(benchmark::State& state) {
  const int W = int(state.range(0));
  const std::string path =
      (std::filesystem::temp_directory_path() / ("envkit_bench_" + std::to_string(::getpid()) + ".envtbl")).string();
  tables(W).save(path);
  for (auto _ : state) {
    EnvTables t = EnvTables::load(path);
    benchmark::DoNotOptimize(t);
  }
  state.SetLabel("mmap + checksums, zero copy, " + std::to_string(std::filesystem::file_size(path) >> 20) + " MiB");
  std::filesystem::remove(path);
}

}  // namespace

BENCHMARK(Sample)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(SampleBatch)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(Pdf)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(Bake)->Arg(1024)->Arg(8192)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Load)->Arg(1024)->Arg(8192)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK_MAIN();
