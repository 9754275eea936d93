// Per-thread product samplers for the integrator (product_sampling.h is not thread-safe: one per thread).
#include "integrator_product.h"

namespace envkit::render {

bool product_sampling_available() { return true; }

ProductSamplers::ProductSamplers(const EnvironmentLight& light, int resolution, double reuse_angle)
    : distribution_(light.distribution(SamplingMethod::Hierarchical, false)),
      rotation_(light.rotation()),
      resolution_(resolution) {
  options_.reuse_angle = reuse_angle;
  // Construct one now so that a bad table (not a pyramid) fails before rendering starts.
  local_.local() = std::make_unique<ProductSampler>(distribution_, rotation_, resolution_, options_);
}

ProductSampler& ProductSamplers::get() const {
  std::unique_ptr<ProductSampler>& sampler = local_.local();
  if (!sampler) sampler = std::make_unique<ProductSampler>(distribution_, rotation_, resolution_, options_);
  return *sampler;
}

void ProductSamplers::begin_pixel() const {
  bool exists = false;
  std::unique_ptr<ProductSampler>& sampler = local_.local(exists);
  if (exists && sampler) sampler->stop_reuse();
}

}  // namespace envkit::render
