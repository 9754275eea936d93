#pragma once
/// @file map_compare.h
/// Comparing two environment maps of any parameterizations and conventions
/// (what envdiff prints): B is resampled onto A's texels (A's parameterization
/// and orientation), then errors are averaged over A's texels that hold data
/// (and that B covers), each weighted by its exact solid angle, so the numbers
/// measure the environments, not their layouts. Colour channels are compared,
/// alpha is not; a one-channel map is compared with every channel of the other.
/// A is the reference R, B the image I:
///   rmse    sqrt(mean((I - R)^2))
///   relmse  mean((I - R)^2 / (R^2 + 0.01))
///   max     the largest |I - R| (with its texel of A and world direction)
///   power   per channel |P_B - P_A| / |P_A| (P = integral of L over the
///   sphere, each map on its own texels;
///           +inf when P_A is 0 and P_B is not)
#include <envkit/envmap/envmap.h>
#include <envkit/resample/filter.h>

#include <string>
#include <vector>

namespace envkit {

struct MaxError {
  double value = 0;
  int i = -1, j = -1, channel = -1;  ///< texel of A and index into
                                     ///< MapComparison::channels; -1 when none
  Vec3 direction;                    ///< world direction of that texel's centre
};

struct MapComparison {
  double rmse = 0, relmse = 0;
  double compared_solid_angle = 0;  ///< steradians of A's texels that entered the means
  MaxError max;
  std::vector<std::string> channels;  ///< names of the compared channels
  std::vector<double> power_a, power_b, power_rel;
  double power_max_rel = 0;
};

/// Compares `b` against the reference `a` (B resampled onto A with `filter`).
/// `path_a` and `path_b` name the maps in the error thrown when their channel
/// counts cannot be compared ("<path_b>: 2 colour channels cannot be compared
/// with the 3 of <path_a>").
MapComparison compare_maps(const EnvMap& a, const EnvMap& b, Filter filter, const std::string& path_a = "A",
                           const std::string& path_b = "B");

/// The value of a metric by name: "rmse", "relmse", "max", "power" (anything
/// else: relmse, as envdiff's default).
double comparison_metric(const MapComparison& comparison, const std::string& metric);

}  // namespace envkit
