#pragma once
/// @file resample.h
/// Resampling an environment from one parameterization (and orientation) to another.
///
/// Point filters (nearest, bilinear, bicubic) reconstruct the source at the direction of each output texel's
/// centre: fast, but they alias when the output is coarser than the source and do not conserve power.
///
/// `area` integrates the source radiance over each output texel's solid angle, so total power (the integral of L
/// over the sphere, per channel) is conserved. It splits the source in two:
///  - texels far brighter than the mean (`hot_contrast`) that each carry more than `hot_fraction` of a channel's
///    power (a sun, a single bright texel) are
///    splatted exactly: each is cut into sub-cells whose exact solid angles sum to the texel's, and each sub-cell's
///    flux goes to the output texel that sees it. Their power is conserved to round-off whatever their size.
///  - the rest is gathered: each output texel is supersampled on an n x n grid, with n adapted to how many source
///    texels its footprint covers (`supersampling` samples per source texel, at most `max_subsamples`), each
///    sub-sample weighted by its exact solid angle and reconstructed bilinearly. A constant map stays exactly
///    constant; power errors of the remaining texels are individually tiny and average out.
/// Longitude wraps, latitude clamps, cube edges re-project, and source texels without data (outside a ball)
/// are excluded: where the source has no data the output's alpha (coverage) is 0, never black light.
/// Work is parallel over output rows (oneTBB); results do not depend on the thread count.
#include <envkit/filter.h>
#include <envkit/image.h>
#include <envkit/parameterization.h>

#include <functional>

namespace envkit {

/// Progress callback: fraction of the work done, in [0, 1]. May be called from worker threads (serialised).
using ProgressFn = std::function<void(double)>;

struct ResampleOptions {
  Filter filter = Filter::Area;
  /// area: sub-samples per source texel along each axis of an output texel's footprint.
  double supersampling = 1.0;
  /// area: cap on the sub-samples per axis of one output texel.
  int max_subsamples = 16;
  /// area: texels carrying more than this fraction of a channel's total power, and brighter than `hot_contrast`
  /// times the map's mean radiance, are splatted exactly.
  double hot_fraction = 1e-6;
  double hot_contrast = 64.0;
  ProgressFn progress;
};

/// A map to read from: image, parameterization, and the matrix taking map-frame directions to world directions.
struct MapRef {
  const Image& image;
  const Parameterization& param;
  Mat3 to_world;
};

/// Resamples `src` into an image laid out by `dst` whose map frame goes to the world by `dst_to_world`.
/// The output keeps the source's channels and names; an alpha (coverage) channel is added when the source has
/// none but does not cover the whole sphere. Metadata is copied from the source.
Image resample(const MapRef& src, const Parameterization& dst, const Mat3& dst_to_world,
               const ResampleOptions& options = {});

/// Total power per channel: sum over texels of L x texel solid angle (double accumulation, deterministic).
std::vector<double> total_power(const Image& image, const Parameterization& param);

}  // namespace envkit
