// Conversion throughput of envkit::resample per filter (nearest, bilinear, bicubic, area), in output texels per
// second (items_per_second), on a synthetic smooth sky with a small bright sun:
//   latlong 2048x1024 -> cube 256 (vstrip), cube 256 -> latlong 2048x1024, latlong 2048x1024 -> octahedral 512.
// The resample uses the default oneTBB thread pool (all cores), like envconvert.
//   bench_resample --benchmark_min_time=0.2   (Debian's Google Benchmark 1.7 wants a plain double)
//   bench_resample --benchmark_filter=area
#include <benchmark/benchmark.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/resample/resample.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

using namespace envkit;

namespace {

/// Radiance of the synthetic sky in world direction d: a smooth RGB gradient (zenith, horizon glow, a slow
/// azimuthal wave, dark ground) plus a sun of 0.5 degrees diameter at ~1e4 x the sky.
void sky_radiance(const Vec3& d, float* rgb) {
  const double y = d.y;
  const double az = std::atan2(d.x, d.z);
  const double sky = y > 0 ? 0.4 + 0.8 * y + 0.3 * std::exp(-10.0 * y) + 0.05 * std::sin(3.0 * az) : 0.15 + 0.05 * y;
  Vec3 sun(0.3, 0.55, 0.6);
  sun.normalize();
  const double cos_sun = d.x * sun.x + d.y * sun.y + d.z * sun.z;
  const double sun_l = cos_sun > std::cos(0.25 * kPi / 180.0) ? 2.0e4 : 0.0;
  rgb[0] = float(0.9 * sky + sun_l);
  rgb[1] = float(1.0 * sky + sun_l);
  rgb[2] = float(1.3 * sky + 0.95 * sun_l);
}

/// The synthetic sky rasterized (one sample at each texel centre) into `param` (whose frame is the world frame).
Image make_map(const Parameterization& param, int width, int height) {
  Image img(width, height, 3);
  for (int j = 0; j < height; ++j)
    for (int i = 0; i < width; ++i) {
      Vec3 d;
      float* px = img.at(i, j);
      if (param.to_direction(Vec2(i + 0.5, j + 0.5), d))
        sky_radiance(d, px);
      else
        px[0] = px[1] = px[2] = 0.0f;
    }
  return img;
}

constexpr int kLatW = 2048, kLatH = 1024, kFace = 256, kOct = 512;

const LatLongMap& latlong_param() {
  static const LatLongMap p(kLatW, kLatH);
  return p;
}
const CubeMap& cube_param() {
  static const CubeMap p(kFace, CubeLayout::VerticalStrip);
  return p;
}
const Image& latlong_image() {
  static const Image img = make_map(latlong_param(), kLatW, kLatH);
  return img;
}
const Image& cube_image() {
  int w = 0, h = 0;
  layout_size(CubeLayout::VerticalStrip, kFace, w, h);
  static const Image img = make_map(cube_param(), w, h);
  return img;
}

void run(benchmark::State& state, const Image& src_img, const Parameterization& src, const Parameterization& dst,
         int out_w, int out_h) {
  const auto filter = static_cast<Filter>(state.range(0));
  ResampleOptions opt;
  opt.filter = filter;
  const MapRef ref{src_img, src, identity3()};
  for (auto _ : state) {
    Image out = resample(ref, dst, identity3(), opt);
    benchmark::DoNotOptimize(out.pixels.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(out_w) * out_h);
  state.SetLabel(filter_name(filter));
}

void BM_latlong_to_cube(benchmark::State& state) {
  int w = 0, h = 0;
  layout_size(CubeLayout::VerticalStrip, kFace, w, h);
  run(state, latlong_image(), latlong_param(), cube_param(), w, h);
}

void BM_cube_to_latlong(benchmark::State& state) {
  run(state, cube_image(), cube_param(), latlong_param(), kLatW, kLatH);
}

void BM_latlong_to_octahedral(benchmark::State& state) {
  static const OctahedralMap oct(kOct);
  run(state, latlong_image(), latlong_param(), oct, kOct, kOct);
}

void filters(benchmark::internal::Benchmark* b) {
  for (Filter f : {Filter::Nearest, Filter::Bilinear, Filter::Bicubic, Filter::Area}) b->Arg(static_cast<int>(f));
  b->ArgName("filter")->Unit(benchmark::kMillisecond)->UseRealTime();
}

}  // namespace

BENCHMARK(BM_latlong_to_cube)->Apply(filters);
BENCHMARK(BM_cube_to_latlong)->Apply(filters);
BENCHMARK(BM_latlong_to_octahedral)->Apply(filters);

BENCHMARK_MAIN();
