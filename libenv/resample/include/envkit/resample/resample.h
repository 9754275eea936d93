#pragma once
/// @file resample.h
/// Resampling an environment from one parameterization (and orientation) to another.
///
/// Point filters (nearest, bilinear, bicubic) reconstruct the source at the direction of each output texel's
/// centre: fast, but they alias when the output is coarser than the source and do not conserve power.
///
/// `area` integrates the source radiance over each output texel's solid angle, so total power (the integral of L
/// over the sphere, per channel) is conserved. Texels far brighter than the mean (`hot_contrast`) that each carry
/// more than `hot_fraction` of a channel's power (a sun, a single bright texel) are splatted exactly: each is cut
/// into sub-cells whose exact solid angles sum to the texel's, and each sub-cell's flux goes to the output texel
/// that sees it, so their power is conserved to round-off whatever their size. The rest goes one of two ways:
///  - gather (magnifying, or similar sizes): each output texel is supersampled on an n x n grid, n adapted to how
///    many source texels its footprint spans (`supersampling` samples per source texel, at most
///    `max_subsamples`), each sub-sample weighted by its solid angle and reconstructed bilinearly;
///  - scatter (shrinking: output texels at least `kScatterMinRatio` times larger than source texels on average):
///    each source texel is visited once, its centre projected into the output, and its flux L x Omega spread over
///    the output texels that a square of its own solid angle, centred there, overlaps (box overlap fractions).
///    Every source texel is read once and no output texel is supersampled, which is what makes shrinking a
///    16k map cheap; the result is the average of the source over each output texel to within the box
///    approximation of the source texels' shape.
/// Both keep a constant map exactly constant (each output texel is normalised by the weight it received); power
/// errors of non-hot texels are individually tiny and average out.
/// Longitude wraps, latitude clamps, cube edges re-project, and source texels without data (outside a ball)
/// are excluded: where the source has no data the output's alpha (coverage) is 0, never black light.
/// Work is parallel (oneTBB); results do not depend on the thread count.
#include <envkit/core/image.h>
#include <envkit/maps/parameterization.h>
#include <envkit/resample/filter.h>

#include <functional>

namespace envkit {

/// Progress callback: fraction of the work done, in [0, 1]. May be called from worker threads (serialised).
using ProgressFn = std::function<void(double)>;

/// How `area` integrates (see above). Auto picks Scatter when shrinking a source that has data in every texel into
/// a lat-long, cube, octahedral or paraboloid map (disk maps' long thin rim texels gather).
enum class AreaMethod { Auto, Gather, Scatter };
/// Auto scatters when output texels are on average at least this many times larger (in solid angle) than source
/// texels.
inline constexpr double kScatterMinRatio = 2.0;

struct ResampleOptions {
  Filter filter = Filter::Area;
  AreaMethod area_method = AreaMethod::Auto;
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

/// The area method Auto resolves to for this pair (source image and its parameterization, destination).
AreaMethod choose_area_method(const Parameterization& src, const Parameterization& dst, const TexelSource& source);

/// Total power per channel: sum over texels of L x texel solid angle (double accumulation, deterministic).
std::vector<double> total_power(const Image& image, const Parameterization& param);

}  // namespace envkit
