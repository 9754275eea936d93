#pragma once
/// @file map_stats.h
/// Per-channel statistics of an environment map (what envinfo prints): power
/// (the integral of the radiance over the sphere, sum of L x exact texel solid
/// angle, double accumulation), the mean radiance power / 4 pi, and min, max
/// and texel mean over the texels that hold data (plain statistics, not
/// weighted by solid angle).
#include <envkit/envmap/envmap.h>

#include <string>
#include <vector>

namespace envkit {

struct ChannelStats {
  std::string name;
  double power = 0, mean_radiance = 0, min = 0, max = 0, texel_mean = 0;
};

struct MapStats {
  double solid_angle = 0;              ///< steradians of the texels with data (4 pi for maps
                                       ///< that cover the sphere)
  std::vector<ChannelStats> channels;  ///< every channel, alpha included
};

MapStats map_statistics(const EnvMap& map);

}  // namespace envkit
