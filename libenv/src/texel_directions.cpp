#include <envkit/latlong.h>
#include <envkit/texel_directions.h>

#include <algorithm>
#include <cmath>

namespace envkit {

TexelDirections::TexelDirections(const Parameterization& param) : param_(param) {
  const auto* latlong = dynamic_cast<const LatLongMap*>(&param);
  if (!latlong) return;
  // The same expressions as LatLongMap::direction_from_uv, evaluated once per column and per row.
  const int W = param.width(), H = param.height();
  sin_lon_.resize(W);
  cos_lon_.resize(W);
  for (int i = 0; i < W; ++i) {
    const double lon = LatLongMap::longitude(latlong->domain_from_image(Vec2(i + 0.5, 0.5)).x);
    sin_lon_[i] = std::sin(lon);
    cos_lon_[i] = std::cos(lon);
  }
  sin_lat_.resize(H);
  cos_lat_.resize(H);
  for (int j = 0; j < H; ++j) {
    const double v = std::clamp(latlong->domain_from_image(Vec2(0.5, j + 0.5)).y, 0.0, 1.0);
    const double lat = LatLongMap::latitude(v);
    sin_lat_[j] = std::sin(lat);
    cos_lat_[j] = std::cos(lat);
  }
}

}  // namespace envkit
