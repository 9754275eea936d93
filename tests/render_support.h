#pragma once
/// @file render_support.h
/// Shared by the renderer tests: integrator options for one strategy in one call, and per-region image statistics.
#include <envkit/render/film.h>
#include <envkit/render/integrator.h>

#include <cstddef>
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

}  // namespace envkit::test
