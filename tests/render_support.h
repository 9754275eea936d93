#pragma once
/// @file render_support.h
/// Shared by the renderer tests: integrator options for one strategy in one call.
#include <envkit/render/integrator.h>

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

}  // namespace envkit::test
