#pragma once
/// @file merge.h
/// Merging partial captures (fisheye photographs, mirror balls shot from
/// different sides, perspective views, any map) into one environment map.
///
/// Each capture's colour (times its mask) goes through the area resampler
/// exactly as a conversion would (flux conserving, a sun splatted exactly), so
/// L_k, its radiance over an output texel, is the flux-weighted mean over the
/// part of the texel the capture sees; with a mask (the capture's mask times
/// its alpha: 1 keeps, 0 drops the camera, the photographer, the tripod),
/// L_k = mean(L x mask) / mask_k, mask_k = mean(mask) over that part. The
/// capture's coverage_k is the exact fraction of the texel's solid angle it
/// sees (its image, its disk): 1 exactly on texels it sees whole, 0 on texels
/// it does not reach, an adaptive quadrature down to 1/256 of a texel on those
/// its edge cuts through. At each output texel capture k gets the weight
///     w_k = coverage_k x mask_k x density_k,
/// density_k = 1 / (the capture's solid angle per pixel where it sees the
/// texel's centre) (a capture that spends more of its pixels on a direction
/// measures it better), and the merged radiance is sum_k w_k L_k / sum_k w_k,
/// times each capture's exposure. Alpha is the fraction of the texel some
/// capture sees (the union of the footprints, exactly) times the largest
/// mask_k there, which is exact without masks or with one capture: a map that
/// covers the sphere merges to itself (alpha 1, the resampler's radiance).
/// Texels no capture sees get radiance 0 and alpha 0 (not data, never black
/// light).
#include <envkit/core/image.h>
#include <envkit/envmap/envmap.h>
#include <envkit/resample/resample.h>

#include <optional>
#include <vector>

namespace envkit {

struct Capture {
  EnvMap map;             ///< the capture, its parameterization and orientation (map frame
                          ///< -> world)
  double exposure = 1.0;  ///< colour multiplier (e.g. 2 for a shot one stop
                          ///< darker than the reference)
  /// Same size as map.image, single channel used: values in [0, 1], 0 drops the
  /// texel. Empty: keep every texel.
  std::optional<Image> mask;
  std::string name;  ///< for reports
};

struct MergeReport {
  /// Solid angle (sr) of the output that no capture sees: sum over texels of
  /// Omega x (1 - alpha).
  double uncovered_solid_angle = 0.0;
  /// Per capture: solid angle it sees (sum of Omega x coverage_k x mask_k) and
  /// the share of the merged weight it carries.
  std::vector<double> covered_solid_angle, weight_share;
};

/// Merges the captures into an RGBA image laid out by `dst`, whose frame goes
/// to the world by `dst_to_world`. Throws Error for an empty list, a capture
/// without 1 or at least 3 colour channels, or a mask of the wrong size.
Image merge_captures(const std::vector<Capture>& captures, const Parameterization& dst, const Mat3& dst_to_world,
                     MergeReport* report = nullptr, const ResampleOptions& options = {});

}  // namespace envkit
