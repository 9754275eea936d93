// Per-thread product samplers for the integrator (product_sampling.h is not thread-safe: one per thread).
#include "integrator_product.h"

#include <envkit/error.h>

#include <string>

namespace envkit::render {

bool product_sampling_available() { return true; }

ProductSamplers::ProductSamplers(const EnvironmentLight& light, int resolution, double reuse_angle)
    : distribution_(light.distribution(SamplingMethod::Hierarchical, false)),
      rotation_(light.rotation()),
      resolution_(resolution) {
  options_.reuse_angle = reuse_angle;
  // Construct one now so that a bad table (not a pyramid, a HEALPix grid) fails before rendering starts, with the
  // table file's name (or the source's, for tables baked in memory).
  try {
    local_.local() = std::make_unique<ProductSampler>(distribution_, rotation_, resolution_, options_);
  } catch (const Error& e) {
    const EnvTables& t = light.tables();
    const std::string where = !t.file_path().empty()    ? t.file_path()
                              : t.source_path().empty() ? std::string("the tables")
                                                        : "the tables of " + t.source_path();
    throw Error(where + ": " + e.what());
  }
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
