// Every strategy renders the same image (the default scene, small): per-region means agree within their
// statistical error (variance AOV); and nothing non-finite appears under a 1e6 sun.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <time.h>

#include <cmath>
#include <cstdio>

#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

/// The default scene at a small environment size, with another probe.
LoadedScene default_scene_with(const std::string& probe_json, int width, int height) {
  std::string text = replace(default_scene_json(), R"("probe": "default", "size": [1024, 512])", probe_json);
  // alpha 0.01 -> 0.05: light sampling alone on a near-mirror lobe is heavy-tailed; at test sample counts its
  // sample variance underestimates its error, so a z-test would compare noise, not bias.
  text = replace(text, R"("rough001": {"type": "conductor", "roughness": 0.01})",
                 R"("rough001": {"type": "conductor", "roughness": 0.05})");
  SceneLoadOptions options;
  options.width = width;
  options.height = height;
  return load_scene_text(text, "default-variant.json", options);
}

/// The default scene with its probe replaced by probe_json and the material entry `from` by `to`, at w x h.
LoadedScene default_scene_replacing(const std::string& probe_json, const std::string& from, const std::string& to,
                                    int width, int height, const std::string& name) {
  std::string text = replace(default_scene_json(), R"("probe": "default", "size": [1024, 512])", probe_json);
  text = replace(text, from, to);
  SceneLoadOptions options;
  options.width = width;
  options.height = height;
  return load_scene_text(text, name, options);
}

double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

struct Named {
  std::string name;
  IntegratorOptions options;
};

std::vector<Named> strategies(bool include_bsdf) {
  std::vector<Named> list;
  auto add = [&](const std::string& name, Strategy s, SamplingMethod m, Heuristic h, int n, int mm) {
    list.push_back({name, envkit::test::strategy_options(s, m, h, n, mm)});
  };
  if (include_bsdf) add("bsdf", Strategy::Bsdf, SamplingMethod::Cdf, Heuristic::Power, 1, 0);
  add("light-cdf", Strategy::Light, SamplingMethod::Cdf, Heuristic::Power, 0, 1);
  add("light-alias", Strategy::Light, SamplingMethod::Alias, Heuristic::Power, 0, 1);
  add("mis-balance", Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Balance, 1, 1);
  add("mis-power", Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  add("mis-power-whole", Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  list.back().options.sun_samples = 0;  // the map as one table, also where it has a sun
  add("mis-compensated", Strategy::MisCompensated, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  add("product", Strategy::Product, SamplingMethod::Hierarchical, Heuristic::Power, 0, 1);
  add("product-mis", Strategy::ProductMis, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  add("auto", Strategy::Auto, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1);
  return list;
}

void check_agreement(const LoadedScene& scene, const std::vector<Named>& list, int spp, double max_z) {
  RenderOptions ro;
  ro.spp = spp;
  const int rx = 4, ry = 2;
  std::vector<std::vector<double>> means, vars;
  for (const Named& s : list) {
    const Integrator integrator(*scene.scene, *scene.light, s.options, &scene.camera);
    const Film film = render_image(scene.camera, integrator, ro);
    EXPECT_EQ(integrator.nonfinite_count(), 0u) << s.name;
    std::vector<double> m, v;
    envkit::test::region_stats(film, rx, ry, m, v);
    means.push_back(m);
    vars.push_back(v);
  }
  // Pairwise against the pooled (inverse-variance weighted) mean of all strategies, per region.
  for (std::size_t r = 0; r < means[0].size(); ++r) {
    double wsum = 0, msum = 0;
    for (std::size_t k = 0; k < list.size(); ++k) {
      const double w = 1.0 / std::max(vars[k][r], 1e-30);
      wsum += w;
      msum += w * means[k][r];
    }
    const double pooled = msum / wsum;
    for (std::size_t k = 0; k < list.size(); ++k) {
      const double z = (means[k][r] - pooled) / std::sqrt(std::max(vars[k][r], 1e-30) + 1.0 / wsum);
      std::printf("  region %zu %-16s mean %.5f  rel.se %.1e  z %+.2f\n", r, list[k].name.c_str(), means[k][r],
                  std::sqrt(vars[k][r]) / std::max(pooled, 1e-30), z);
      EXPECT_LT(std::abs(z), max_z) << list[k].name << " region " << r << " mean " << means[k][r] << " vs pooled "
                                    << pooled;
    }
  }
}

}  // namespace

TEST(RenderStrategies, AllAgreeOnTheDefaultSceneUnderAnOvercastSky) {
  const LoadedScene scene = default_scene_with(R"("probe": "overcast", "size": [256, 128])", 48, 24);
  check_agreement(scene, strategies(true), 32, 4.0);
}

TEST(RenderStrategies, LightSamplingStrategiesAgreeOnTheSunnyDefaultScene) {
  // With the default probe's sun (3e4, 0.27 deg), BSDF sampling alone almost never finds the sun: its variance
  // estimate is meaningless at a few samples, so it is left out here (it is checked under the overcast sky).
  const LoadedScene scene = default_scene_with(R"("probe": "default", "size": [256, 128])", 48, 24);
  // The sun is split off (sun_split.h) by the strategies that sample the light, except mis-power-whole.
  EXPECT_NE(Integrator(*scene.scene, *scene.light, IntegratorOptions{}).sun_split(), nullptr);
  check_agreement(scene, strategies(false), 64, 4.0);
}

TEST(RenderStrategies, NoNonFiniteValuesUnderAMillionSun) {
  const LoadedScene scene = default_scene_with(
      R"("probe": "sun", "radiance": 1e6, "sky": 1e-3, "radius_deg": 0.1, "elevation_deg": 40, "azimuth_deg": 20, "size": [256, 128])",
      32, 16);
  for (auto s : strategies(true)) {
    for (int depth : {1, 3}) {
      s.options.max_depth = depth;
      const Integrator integrator(*scene.scene, *scene.light, s.options, &scene.camera);
      RenderOptions ro;
      ro.spp = 4;
      const Film film = render_image(scene.camera, integrator, ro);
      EXPECT_EQ(integrator.nonfinite_count(), 0u) << s.name;
      EXPECT_GT(envkit::test::expect_finite_film(film, s.name), 0.0) << s.name;
    }
  }
}

TEST(RenderStrategies, MirrorSphereUnderTheSunInEveryStrategy) {
  // A mirror sphere in the default scene's place of the matte one: every strategy renders it identically, since
  // delta lobes are followed by BSDF sampling with weight 1 whatever the strategy.
  const LoadedScene scene = default_scene_replacing(
      R"("probe": "default", "size": [256, 128])", R"("matte":    {"type": "diffuse", "albedo": [0.75, 0.3, 0.2]})",
      R"("matte":    {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]})", 48, 24, "mirror.json");
  RenderOptions ro;
  ro.spp = 4;
  ro.crop = Crop{20, 4, 28, 10};  // the mirror sphere (behind the middle glossy one)
  std::vector<Film> films;
  for (const Named& s : strategies(true)) {
    const Integrator integrator(*scene.scene, *scene.light, s.options);
    films.push_back(render_image(scene.camera, integrator, ro));
  }
  // Pixels whose mirror ray escapes directly are deterministic given the jitter: same in every strategy.
  int identical = 0;
  for (int y = 0; y < films[0].height(); ++y)
    for (int x = 0; x < films[0].width(); ++x) {
      bool same = true;
      for (const Film& f : films)
        same = same && std::abs(f.mean(x, y).y - films[0].mean(x, y).y) <= 1e-9 * films[0].mean(x, y).y;
      identical += same;
    }
  EXPECT_GT(identical, 0);
}

// Pixels depend on the seed only: not on the crop, the tile size or the thread count (also with product tables:
// a shading point's table depends on its lobe and axis alone).
TEST(RenderStrategies, CropAndThreadCountDoNotChangePixels) {
  // A glossy ground: neighbouring pixels draw from neighbouring axis bins of the product tables.
  const LoadedScene scene = default_scene_replacing(
      R"("probe": "overcast", "size": [64, 32])", R"("ground":   {"type": "diffuse", "albedo": [0.45, 0.45, 0.42]})",
      R"("ground":   {"type": "conductor", "roughness": 0.3})", 24, 12, "glossy-ground.json");
  IntegratorOptions mis, product, automatic;
  mis.strategy = Strategy::Mis;
  product.strategy = Strategy::ProductMis;
  automatic.strategy = Strategy::Auto;
  for (const IntegratorOptions& options : {mis, product, automatic}) {
    SCOPED_TRACE(strategy_name(options.strategy));
    RenderOptions ro;
    ro.spp = 3;
    ro.seed = 42;
    // One thread for the tables (the sun split, the product tables, auto's pilot) as well as for the pixels.
    const Film full = envkit::test::expect_crop_matches(scene, options, ro, Crop{5, 3, 17, 10}, 4);
    // Another seed gives another image.
    const Integrator integrator(*scene.scene, *scene.light, options, &scene.camera);
    ro.seed = 43;
    const Film other = render_image(scene.camera, integrator, ro);
    EXPECT_NE(other.mean(12, 6), full.mean(12, 6));
  }
}

TEST(RenderStrategies, TimeBudgetRendersWholePasses) {
  const LoadedScene scene = default_scene_with(R"("probe": "overcast", "size": [64, 32])", 8, 4);
  const Integrator integrator(*scene.scene, *scene.light, IntegratorOptions{});
  RenderOptions ro;
  ro.time_seconds = 0.2;
  RenderStats stats;
  const Film film = render_image(scene.camera, integrator, ro, &stats);
  EXPECT_GE(stats.spp, 1);
  EXPECT_GE(stats.seconds, 0.2);
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) EXPECT_EQ(film.count(x, y), std::uint64_t(stats.spp));
}

// RenderOptions::pixel_seconds times each pixel's samples and changes none of them: the sums are the same bits,
// every pixel's time is positive and finite, and on one thread (the caller's) the pixels' times add up to most of
// the CPU time the render took on it, and never more than that or its wall time.
TEST(RenderStrategies, PixelSecondsTimeEveryPixelAndChangeNoValue) {
  const LoadedScene scene = default_scene_with(R"("probe": "default", "size": [64, 32])", 24, 12);
  IntegratorOptions options;
  options.strategy = Strategy::Auto;
  const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  const Integrator integrator(*scene.scene, *scene.light, options, &scene.camera);
  RenderOptions ro;
  ro.spp = 16;
  ro.seed = 5;
  const Film plain = render_image(scene.camera, integrator, ro);
  EXPECT_FALSE(plain.timed());
  ro.pixel_seconds = true;
  RenderStats stats;
  const double cpu_start = thread_cpu_seconds();
  const Film timed = render_image(scene.camera, integrator, ro, &stats);
  const double cpu = thread_cpu_seconds() - cpu_start;
  ASSERT_TRUE(timed.timed());
  double sum = 0.0;
  for (int y = 0; y < timed.height(); ++y)
    for (int x = 0; x < timed.width(); ++x) {
      const Film::Pixel &a = plain.pixel(x, y), &b = timed.pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(a.sum[c], b.sum[c]) << x << "," << y;
        EXPECT_EQ(a.sum_sq[c], b.sum_sq[c]) << x << "," << y;
      }
      EXPECT_EQ(a.count, b.count);
      const double s = timed.seconds(x, y);
      EXPECT_TRUE(std::isfinite(s) && s > 0.0) << x << "," << y << ": " << s;
      sum += s;
    }
  EXPECT_LE(sum, stats.seconds);
  EXPECT_LE(sum, cpu);
  EXPECT_GE(sum, 0.5 * cpu);
}
