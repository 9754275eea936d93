// Cost of BSDF x environment product sampling (renderer/include/envkit/render/product_sampling.h) against
// --product-resolution, on a 2048 x 1024 sky-plus-sun lat-long pyramid:
//   prepare/<res>   per-shading-point table (BSDF at S x S points per coarse node, S = 2 up to 16 columns, 1 above + sum pyramid), ns per call
//   sample/<res>    ns per product sample after prepare (independent random u)
//   pdf/<res>       ns per pdf() of a direction
//   env_sample      baseline: plain hierarchical environment sampling (SphericalDistribution::sample)
// Materials: a glossy conductor (alpha 0.1) and a diffuse one; shading normals and wo cycle through 64 random
// configurations so that prepare() does not run on a warm, identical table.
//   bench_product --benchmark_filter=sample
#include <envkit/distribution_pyramid.h>
#include <envkit/env_sampling.h>
#include <envkit/latlong.h>
#include <envkit/render/frame.h>
#include <envkit/render/material.h>
#include <envkit/render/product_sampling.h>

#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

using namespace envkit;
using namespace envkit::render;

namespace {

constexpr int kW = 2048, kH = 1024;

/// Sky gradient plus a ~0.5 degree sun carrying ~90% of the power; weights = radiance x texel solid angle.
const SphericalDistribution& environment() {
  static const std::unique_ptr<SphericalDistribution> env = [] {
    const LatLongMap map(kW, kH);
    std::vector<float> w(std::size_t(kW) * std::size_t(kH));
    const Vec3 sun = Vec3(0.4, 0.5, -0.6).normalized();
    double sky_power = 0.0;
    std::vector<std::size_t> sun_texels;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const Vec3 d = LatLongMap::direction_from_uv((x + 0.5) / kW, (y + 0.5) / kH);
        const double L = 0.2 + 0.8 * std::max(0.0, d.y) + 0.1 * d.x;
        const std::size_t k = std::size_t(y) * std::size_t(kW) + std::size_t(x);
        w[k] = float(L * map.row_solid_angle(y));
        sky_power += w[k];
        if (angle_between(d, sun) < 0.0045) sun_texels.push_back(k);
      }
    for (std::size_t k : sun_texels) w[k] += float(9.0 * sky_power / double(sun_texels.size()));
    return std::make_unique<SphericalDistribution>(Kind::LatLong,
                                                   std::make_shared<PyramidDistribution2D>(w.data(), kW, kH));
  }();
  return *env;
}

struct ShadingPoint {
  Frame frame;
  Vec3 wo;
};

const std::vector<ShadingPoint>& shading_points() {
  static const std::vector<ShadingPoint> points = [] {
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<ShadingPoint> p;
    for (int i = 0; i < 64; ++i) {
      const double z = 2.0 * U(rng) - 1.0, phi = kTwoPi * U(rng), r = std::sqrt(1.0 - z * z);
      const double zo = 0.1 + 0.9 * U(rng), po = kTwoPi * U(rng), ro = std::sqrt(1.0 - zo * zo);
      p.push_back({Frame::from_normal(Vec3(r * std::cos(phi), z, r * std::sin(phi))),
                   Vec3(ro * std::cos(po), ro * std::sin(po), zo)});
    }
    return p;
  }();
  return points;
}

const std::vector<Vec2>& random_u() {
  static const std::vector<Vec2> u = [] {
    std::mt19937_64 rng(7);
    std::vector<Vec2> v(1 << 16);
    for (Vec2& x : v) x = Vec2(double(rng() >> 11) * 0x1p-53, double(rng() >> 11) * 0x1p-53);
    return v;
  }();
  return u;
}

std::unique_ptr<Material> material(int kind) {
  return kind == 0 ? make_conductor(Vec3(0.2, 0.4, 1.4), Vec3(3.9, 2.4, 1.6), 0.1) : make_diffuse(Vec3(0.6));
}

void BM_ProductPrepare(benchmark::State& state) {
  const auto m = material(int(state.range(1)));
  ProductSampler ps(environment(), identity3(), int(state.range(0)));
  const auto& points = shading_points();
  std::size_t i = 0;
  double lobe_nodes = 0.0;
  for (auto _ : state) {
    const ShadingPoint& p = points[i++ & 63];
    ps.prepare(*m, p.frame, p.wo);
    benchmark::DoNotOptimize(ps.valid());
    lobe_nodes += ps.lobe_node_count();
  }
  state.counters["lobe_nodes"] = lobe_nodes / double(std::max<std::size_t>(i, 1));
  state.counters["nodes"] = double(ps.coarse_width() * ps.coarse_height());
  state.counters["points"] = double(ps.points_per_axis() * ps.points_per_axis());
  state.SetLabel(m->name());
}

void BM_ProductSample(benchmark::State& state) {
  const auto m = material(int(state.range(1)));
  ProductSampler ps(environment(), identity3(), int(state.range(0)));
  const ShadingPoint& p = shading_points()[3];
  ps.prepare(*m, p.frame, p.wo);
  const auto& u = random_u();
  std::size_t i = 0;
  for (auto _ : state) {
    Vec3 wi;
    double pdf = 0.0;
    benchmark::DoNotOptimize(ps.sample(u[i++ & 0xffff], wi, pdf));
    benchmark::DoNotOptimize(wi);
    benchmark::DoNotOptimize(pdf);
  }
  state.SetItemsProcessed(int64_t(state.iterations()));
  state.SetLabel(m->name());
}

void BM_ProductPdf(benchmark::State& state) {
  const auto m = material(int(state.range(1)));
  ProductSampler ps(environment(), identity3(), int(state.range(0)));
  const ShadingPoint& p = shading_points()[3];
  ps.prepare(*m, p.frame, p.wo);
  std::vector<Vec3> dirs;
  for (const Vec2& u : random_u()) {
    Vec3 wi;
    double pdf = 0.0;
    if (ps.sample(u, wi, pdf)) dirs.push_back(wi);
    if (dirs.size() == 4096) break;
  }
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(ps.pdf(dirs[i++ & 4095]));
  state.SetLabel(m->name());
}

void BM_EnvSample(benchmark::State& state) {
  const SphericalDistribution& env = environment();
  const auto& u = random_u();
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(env.sample(u[i++ & 0xffff]));
  state.SetItemsProcessed(int64_t(state.iterations()));
}

void resolutions(benchmark::internal::Benchmark* b) {
  for (int material_kind : {0, 1})
    for (int res : {1, 4, 8, 16, 32, 64, 128, 256}) b->Args({res, material_kind});
  b->ArgNames({"res", "diffuse"});
}

}  // namespace

BENCHMARK(BM_ProductPrepare)->Apply(resolutions)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ProductSample)->Apply(resolutions);
BENCHMARK(BM_ProductPdf)->Apply(resolutions);
BENCHMARK(BM_EnvSample);

BENCHMARK_MAIN();
