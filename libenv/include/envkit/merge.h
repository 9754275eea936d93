#pragma once
/// @file merge.h
/// Merging partial captures (fisheye photographs, mirror balls shot from
/// different sides, perspective views, any map) into one environment map.
///
/// Each capture is resampled into the output with the area filter, its colour
/// scaled by its exposure and multiplied by its mask (1 keeps, 0 drops: the
/// camera, the photographer, the tripod), the mask resampled alongside as an
/// extra channel, and its coverage (the part of each output texel it sees) from
/// the resampler's alpha. At each output texel, capture k gets the weight
///     w_k = coverage_k x mask_k x density_k,   density_k = 1 / (capture's
///     solid angle per pixel where it sees
///                                                             the texel's
///                                                             centre)
/// (a capture that spends more of its pixels on a direction measures it
/// better), and the merged radiance is sum_k w_k L_k / sum_k w_k, with L_k the
/// capture's masked mean over the texel. Texels no capture sees get radiance 0
/// and alpha 0 (not data, never black light); alpha is the largest coverage x
/// mask any capture has there.
#include <envkit/envmap.h>
#include <envkit/image.h>
#include <envkit/resample.h>

#include <optional>
#include <vector>

namespace envkit {

struct Capture {
  EnvMap map; ///< the capture, its parameterization and orientation (map frame
              ///< -> world)
  double exposure = 1.0; ///< colour multiplier (e.g. 2 for a shot one stop
                         ///< darker than the reference)
  /// Same size as map.image, single channel used: values in [0, 1], 0 drops the
  /// texel. Empty: keep every texel.
  std::optional<Image> mask;
  std::string name; ///< for reports
};

struct MergeReport {
  /// Solid angle (sr) of the output that no capture sees: sum over texels of
  /// Omega x (1 - alpha).
  double uncovered_solid_angle = 0.0;
  /// Per capture: solid angle it sees (after its mask) and the share of the
  /// merged weight it carries.
  std::vector<double> covered_solid_angle, weight_share;
};

/// Merges the captures into an RGBA image laid out by `dst`, whose frame goes
/// to the world by `dst_to_world`. Throws Error for an empty list, a capture
/// without 1 or at least 3 colour channels, or a mask of the wrong size.
Image merge_captures(const std::vector<Capture> &captures,
                     const Parameterization &dst, const Mat3 &dst_to_world,
                     MergeReport *report = nullptr,
                     const ResampleOptions &options = {});

} // namespace envkit
