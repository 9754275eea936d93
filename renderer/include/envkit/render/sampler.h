#pragma once
/// @file sampler.h
/// The renderer's sampler is libenv's Owen-scrambled Sobol sampler (envkit/sampling/sampler.h), shared with envsample.
#include <envkit/sampling/sampler.h>

namespace envkit::render {
using Sampler = envkit::OwenSobolSampler;
using envkit::hash_combine;
using envkit::hash_u32;
}  // namespace envkit::render
