#include <envkit/maps/param_factory.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/filter.h>
#include <envkit/resample/map_size.h>

#include <algorithm>
#include <cmath>

namespace envkit {

std::size_t data_texel_count(const Image& image, const Parameterization& param) {
  const TexelSource source(image, param);
  if (source.fully_covered()) return image.texel_count();
  std::size_t n = 0;
  for (std::size_t t = 0; t < image.texel_count(); ++t) n += source.covered(t) ? 1 : 0;
  return n;
}

int matching_natural_size(std::size_t texels, Kind kind, const Convention& conv, std::optional<CubeLayout> layout) {
  return matching_natural_size(texels, [&](int n) { return spec_for(kind, n, conv, layout); });
}

int matching_natural_size(std::size_t texels, const std::function<ParamSpec(int)>& spec_at) {
  constexpr int probe_n = 64;
  const auto probe = make_parameterization(spec_at(probe_n));
  const Image blank(probe->width(), probe->height(), 1);
  const double per_n2 = double(data_texel_count(blank, *probe)) / (double(probe_n) * probe_n);
  const double seen = std::min(1.0, SolidAngleTable(*probe).total() / kFourPi);
  const double n = std::sqrt(double(texels) * seen / per_n2);
  const long rounded = n >= 64.0 ? 8 * std::lround(n / 8.0) : std::lround(n);  // 1182.4 -> 1184, 9.4 -> 9
  return static_cast<int>(std::clamp(rounded, 1L, long(1) << 17));
}

}  // namespace envkit
