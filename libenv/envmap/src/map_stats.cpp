#include <envkit/envmap/map_stats.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/filter.h>
#include <envkit/resample/resample.h>

#include <algorithm>
#include <limits>

namespace envkit {

MapStats map_statistics(const EnvMap& map) {
  const Image& img = map.image;
  const int C = img.channels;
  MapStats s;
  s.solid_angle = SolidAngleTable(*map.param).total();
  const std::vector<double> power = total_power(img, *map.param);
  const TexelSource source(img, *map.param);
  std::vector<double> lo(C, std::numeric_limits<double>::infinity()), hi(C, -lo[0]), sum(C, 0.0);
  std::size_t count = 0;
  for (std::size_t t = 0; t < img.texel_count(); ++t) {
    if (!source.covered(t)) continue;
    ++count;
    const float* px = img.pixels.data() + t * C;
    for (int c = 0; c < C; ++c) {
      lo[c] = std::min(lo[c], double(px[c]));
      hi[c] = std::max(hi[c], double(px[c]));
      sum[c] += px[c];
    }
  }
  for (int c = 0; c < C; ++c)
    s.channels.push_back({img.channel_names[c], power[c], power[c] / kFourPi, count ? lo[c] : 0.0, count ? hi[c] : 0.0,
                          count ? sum[c] / double(count) : 0.0});
  return s;
}

}  // namespace envkit
