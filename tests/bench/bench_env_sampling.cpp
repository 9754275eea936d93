// Benchmarks of direction sampling from baked tables (env_sampling.h / env_tables.h) on a sky-plus-sun lat-long
// at 1024x512 and 8192x4096: ns per sample (u -> direction + pdf + texel) and per pdf(direction) for cdf,
// alias and hierarchical; the bake from an in-memory image; loading the same tables from a file.
//   bench_env_sampling --benchmark_filter=Sample      (Sample: one sample() per call; SampleBatch: batched)
//   bench_env_sampling --benchmark_filter='Bake|Load'
//   bench_env_sampling --benchmark_filter=Product   (product tables: a shading point's table choice, draws and pdfs)
#include <benchmark/benchmark.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/sampling/lobe_product.h>
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

/// Product tables (lobe_product.h) over the 1024x512 sky for a scene's worth of lobes (the cosine and eight GGX
/// alphas: 7 424 tables, ~25 MiB, more than the L2 cache), used as envrender uses them at a shading point with two
/// lobes (a plastic): the two lobes' tables for a random axis each, then 4 draws from their mixture, drawn together
/// (SphericalDistribution::sample_each), each with both tables' texel_pdf, as EnvironmentLight::sample does them and 4
/// lookups of other directions (texel_of, then both tables' texel_pdf: a BSDF sample's MIS weight, as
/// EnvironmentLight::lookup). Time per shading point; per_draw = that over its 8 draws and lookups. range(0): 0 = a new
/// table pair and new u per point (cold tables), 1 = the same point every time (warm caches, predictable branches: the
/// arithmetic alone), 2 = one table pair, new u.
void ProductPoint(benchmark::State& state) {
  static const std::vector<Lobe> lobes = {
      {Lobe::Shape::Cosine, 1.0}, {Lobe::Shape::Ggx, 0.01}, {Lobe::Shape::Ggx, 0.0225},
      {Lobe::Shape::Ggx, 0.05},   {Lobe::Shape::Ggx, 0.09}, {Lobe::Shape::Ggx, 0.15},
      {Lobe::Shape::Ggx, 0.25},   {Lobe::Shape::Ggx, 0.3},  {Lobe::Shape::Ggx, 0.5}};
  static const LobeProductTables product(*tables(1024).distribution(SamplingMethod::Hierarchical), lobes);
  const bool warm = state.range(0) == 1;  // one point
  constexpr std::size_t kPoints = 1 << 12;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const auto direction = [&] {
    const double z = 2.0 * U(rng) - 1.0, phi = 2.0 * kPi * U(rng), r = std::sqrt(std::max(0.0, 1.0 - z * z));
    return Vec3(r * std::cos(phi), z, r * std::sin(phi));
  };
  struct Point {
    Vec3 axis;
    int lobe;
    Vec2 u[4];
    Vec3 lookup[4];
  };
  std::vector<Point> points(kPoints);
  for (Point& p : points) {
    p.axis = direction();
    p.lobe = 1 + int(U(rng) * double(lobes.size() - 1));
    for (Vec2& u : p.u) u = Vec2(U(rng), U(rng));
    for (Vec3& d : p.lookup) d = direction();
  }
  std::size_t i = 0;
  for (auto _ : state) {
    const Point& p = points[warm ? 0 : i++ & (kPoints - 1)];
    const Point& q = state.range(0) == 2 ? points[0] : p;
    const SphericalDistribution& wide = product.table(0, q.axis).distribution;
    const SphericalDistribution& narrow = product.table(q.lobe, q.axis).distribution;
    double sum = 0.0;
    const SphericalDistribution* from[4] = {&wide, &narrow, &wide, &narrow};
    DirectionSample drawn[4];
    SphericalDistribution::sample_each(from, p.u, drawn);
    for (const DirectionSample& s : drawn)
      sum += 0.5 * wide.texel_pdf(s.x, s.y) + 0.5 * narrow.texel_pdf(s.x, s.y) + s.direction.x;
    for (const Vec3& d : p.lookup) {
      int x = 0, y = 0;
      wide.texel_of(d, x, y);
      sum += 0.5 * wide.texel_pdf(x, y) + 0.5 * narrow.texel_pdf(x, y);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["per_draw"] =
      benchmark::Counter(8.0, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  const char* what[] = {"a table pair per point", "one point (warm)", "one table pair, new u"};
  state.SetLabel(std::string(what[state.range(0)]) + ", " + std::to_string(product.bytes() >> 20) + " MiB of tables");
}

}  // namespace

BENCHMARK(Sample)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(SampleBatch)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(Pdf)->ArgsProduct({{1024, 8192}, {0, 1, 2}});
BENCHMARK(ProductPoint)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK(Bake)->Arg(1024)->Arg(8192)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(Load)->Arg(1024)->Arg(8192)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK_MAIN();
