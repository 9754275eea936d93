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
  ProductSamplers(const EnvironmentLight& light, int resolution);
  /// This thread's sampler (created on first use).
  ProductSampler& get() const;

 private:
  const SphericalDistribution& distribution_;
  Mat3 rotation_;
  int resolution_;
  mutable tbb::enumerable_thread_specific<std::unique_ptr<ProductSampler>> local_;
};

}  // namespace envkit::render
