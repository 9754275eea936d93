#pragma once
// Per-thread ProductSampler instances shared by the integrator's product strategies.
#include <envkit/render/env_light.h>
#include <envkit/render/integrator.h>
#include <envkit/render/product_sampling.h>

#include <tbb/enumerable_thread_specific.h>

#include <memory>

namespace envkit::render {

class ProductSamplers {
 public:
  /// Throws Error when the light has no hierarchical table (product sampling descends its pyramid).
  /// reuse_angle: ProductSampler::Options::reuse_angle (radians).
  ProductSamplers(const EnvironmentLight& light, int resolution, double reuse_angle);
  /// This thread's sampler (created on first use).
  ProductSampler& get() const;
  /// A pixel starts on this thread: its sampler stops reusing the previous pixel's table.
  void begin_pixel() const;

 private:
  const SphericalDistribution& distribution_;
  Mat3 rotation_;
  int resolution_;
  ProductSampler::Options options_;
  mutable tbb::enumerable_thread_specific<std::unique_ptr<ProductSampler>> local_;
};

}  // namespace envkit::render
