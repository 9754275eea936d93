// callgrind_sample: draws N samples of ONE sampling method from tables baked from a synthetic sky + sun
// lat-long map, for instruction counting under callgrind (not a Google Benchmark program).
//
//   callgrind_sample METHOD LEVEL WIDTH N [--twice]
//     METHOD  cdf | alias | hierarchical
//     LEVEL   2d (Distribution2D::sample, uv space) | sphere (SphericalDistribution::sample, directions) | both
//     WIDTH   lat-long width (height WIDTH / 2), e.g. 1024 or 8192
//     N       number of samples
//     --twice run each loop with N and then with 2N samples in the same process (the bake is what takes long
//             under valgrind, ~2 min at 8192x4096), dumping the callgrind counters after each loop
//             (CALLGRIND_DUMP_STATS_AT("METHOD LEVEL n=K"): one numbered file per loop).
//
// Only the requested method's table is baked (EnvTables::bake with one method). The N random u (53-bit doubles,
// mt19937_64, fixed seed) are generated before the sampling loop. When built with valgrind's client requests
// (valgrind/callgrind.h), instrumentation is switched on just around the sampling loop, so
//   valgrind --tool=callgrind --instr-atstart=no callgrind_sample cdf 2d 8192 100000
// counts (almost) nothing but the loop and runs the bake at un-instrumented speed. Running with N and 2N and
// subtracting the totals gives the instructions per sample with the loop's fixed overheads removed.
// Without valgrind it prints a checksum of the samples (so the loop cannot be optimised away) and the wall time.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define ENVKIT_CG_START() CALLGRIND_START_INSTRUMENTATION
#define ENVKIT_CG_STOP() CALLGRIND_STOP_INSTRUMENTATION
#define ENVKIT_CG_ZERO() CALLGRIND_ZERO_STATS
#define ENVKIT_CG_DUMP(name) CALLGRIND_DUMP_STATS_AT(name)
#else
#define ENVKIT_CG_ZERO() ((void)0)
#define ENVKIT_CG_DUMP(name) ((void)(name))
#define ENVKIT_CG_START() ((void)0)
#define ENVKIT_CG_STOP() ((void)0)
#endif

using namespace envkit;

namespace {

/// RGB sky (brighter towards the zenith) with a ~0.5 degree sun of radiance 4e5 carrying ~90% of the power:
/// the same map as tests/bench/bench_env_sampling.cpp.
EnvMap sky(int W, int H) {
  EnvMap env;
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

// The sampling loops are kept out of line so that a profile (or --toggle-collect) can name them.
__attribute__((noinline)) double loop_2d(const Distribution2D& d, const std::vector<Vec2>& u) {
  double acc = 0.0;
  for (const Vec2& v : u) {
    const DistributionSample s = d.sample(v);
    acc += s.uv.x + s.uv.y + s.pdf + s.x + s.y;
  }
  return acc;
}

__attribute__((noinline)) double loop_sphere(const SphericalDistribution& d, const std::vector<Vec2>& u) {
  double acc = 0.0;
  for (const Vec2& v : u) {
    const DirectionSample s = d.sample(v);
    acc += s.direction.x + s.direction.y + s.direction.z + s.pdf + s.x + s.y;
  }
  return acc;
}

int usage() {
  std::fprintf(stderr, "usage: callgrind_sample cdf|alias|hierarchical 2d|sphere|both WIDTH N [--twice]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5 && argc != 6) return usage();
  const std::string method_arg = argv[1], level_arg = argv[2];
  const int W = std::atoi(argv[3]);
  const long long n = std::atoll(argv[4]);
  const bool twice = argc == 6 && std::string(argv[5]) == "--twice";
  if (argc == 6 && !twice) return usage();
  if ((level_arg != "2d" && level_arg != "sphere" && level_arg != "both") || W < 2 || W % 2 != 0 || n < 1)
    return usage();
  try {
    const SamplingMethod method = parse_method(method_arg);
    BakeOptions options;
    options.cdf = method == SamplingMethod::Cdf;
    options.alias = method == SamplingMethod::Alias;
    options.hierarchical = method == SamplingMethod::Hierarchical;
    const EnvTables tables = [&] {
      const EnvMap env = sky(W, W / 2);
      return EnvTables::bake(env, options, "", "synthetic");
    }();
    const SphericalDistribution& d = *tables.distribution(method);

    const std::size_t total = static_cast<std::size_t>(twice ? 2 * n : n);
    std::mt19937_64 rng(20261123);
    std::vector<Vec2> u(total);
    for (Vec2& v : u) v = Vec2(double(rng() >> 11) * 0x1p-53, double(rng() >> 11) * 0x1p-53);

    std::vector<std::string> levels;
    if (level_arg == "both")
      levels = {"2d", "sphere"};
    else
      levels = {level_arg};
    for (const std::string& level : levels)
      for (long long count : twice ? std::vector<long long>{n, 2 * n} : std::vector<long long>{n}) {
        const std::vector<Vec2> us(u.begin(), u.begin() + count);
        const std::string name = std::string(method_name(method)) + " " + level + " n=" + std::to_string(count);
        const auto t0 = std::chrono::steady_clock::now();
        ENVKIT_CG_ZERO();
        ENVKIT_CG_START();
        const double acc = level == "2d" ? loop_2d(d.distribution(), us) : loop_sphere(d, us);
        ENVKIT_CG_STOP();
        if (twice) ENVKIT_CG_DUMP(name.c_str());
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("method=%s level=%s size=%dx%d samples=%lld checksum=%.17g ns_per_sample=%.2f\n",
                    method_name(method), level.c_str(), W, W / 2, count, acc, seconds * 1e9 / double(count));
      }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "callgrind_sample: %s\n", e.what());
    return 1;
  }
  return 0;
}
