#pragma once
/// @file render_support.h
/// Shared by the renderer tests: integrator options for one strategy in one call, per-region image statistics, and
/// the checks every strategy must pass (finite, non-negative pixels; pixels independent of crop, tiles and threads).
#include <envkit/render/film.h>
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

namespace envkit::test {

inline render::IntegratorOptions strategy_options(render::Strategy strategy, SamplingMethod method,
                                                  render::Heuristic heuristic, int bsdf_samples, int light_samples) {
  render::IntegratorOptions o;
  o.strategy = strategy;
  o.light_method = method;
  o.heuristic = heuristic;
  o.bsdf_samples = bsdf_samples;
  o.light_samples = light_samples;
  return o;
}

/// Per-region means (rx x ry regions) of the green channel with their variances (sum of pixel variances / n^2).
inline void region_stats(const render::Film& film, int rx, int ry, std::vector<double>& mean,
                         std::vector<double>& var) {
  mean.assign(std::size_t(rx * ry), 0.0);
  var.assign(std::size_t(rx * ry), 0.0);
  std::vector<int> count(std::size_t(rx * ry), 0);
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) {
      const std::size_t r = std::size_t((y * ry / film.height()) * rx + x * rx / film.width());
      mean[r] += film.mean(x, y).y;
      var[r] += film.variance(x, y).y;
      ++count[r];
    }
  for (std::size_t r = 0; r < mean.size(); ++r) {
    mean[r] /= count[r];
    var[r] /= double(count[r]) * count[r];
  }
}

/// Expects every pixel's mean and variance of `film` finite and >= 0 (one failure, at the first bad pixel); returns
/// the sum of the green means.
inline double expect_finite_film(const render::Film& film, const std::string& what) {
  double total = 0.0;
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) {
      const Vec3 m = film.mean(x, y), v = film.variance(x, y);
      for (int c = 0; c < 3; ++c)
        if (!(std::isfinite(m[c]) && m[c] >= 0.0 && std::isfinite(v[c]) && v[c] >= 0.0)) {
          ADD_FAILURE() << what << " pixel " << x << "," << y << " mean " << m[c] << " variance " << v[c];
          return total;
        }
      total += m.y;
    }
  return total;
}

/// Renders the scene with `options` in full (`ro`'s spp and seed, all threads), then `crop` in tiles of `tile` on one
/// thread (the integrator built on that thread too), and expects the crop's pixels to be the full render's. Returns
/// the full render.
inline render::Film expect_crop_matches(const render::LoadedScene& scene, const render::IntegratorOptions& options,
                                        render::RenderOptions ro, const render::Crop& crop, int tile) {
  const render::Integrator integrator(*scene.scene, *scene.light, options, &scene.camera);
  ro.crop = render::Crop{};
  const render::Film full = render_image(scene.camera, integrator, ro);
  ro.crop = crop;
  ro.tile_size = tile;
  render::Film part;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    const render::Integrator serial(*scene.scene, *scene.light, options, &scene.camera);
    part = render_image(scene.camera, serial, ro);
  }
  for (int y = 0; y < part.height(); ++y)
    for (int x = 0; x < part.width(); ++x) {
      EXPECT_EQ(part.mean(x, y), full.mean(x + crop.x0, y + crop.y0)) << x << "," << y;
      EXPECT_EQ(part.variance(x, y), full.variance(x + crop.x0, y + crop.y0)) << x << "," << y;
      EXPECT_EQ(part.count(x, y), std::uint64_t(ro.spp)) << x << "," << y;
    }
  return full;
}

}  // namespace envkit::test
