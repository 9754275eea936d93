#pragma once
/// @file texel_directions.h
/// Directions of texel centres (map frame), for loops that visit every texel of a map.
///
/// Lat-long maps are separable: LatLongMap::centre_angles() gives one sin/cos table per column and per row, which
/// replaces the trigonometry per texel (bit-identical to LatLongMap::to_direction at the centre). Other maps call
/// Parameterization::to_direction.
#include <envkit/maps/latlong.h>
#include <envkit/maps/parameterization.h>

namespace envkit {

class TexelDirections {
 public:
  /// Keeps a reference to `param`, which must outlive this object.
  explicit TexelDirections(const Parameterization& param);

  /// Unit direction seen at the centre (i + 0.5, j + 0.5) of texel (i, j); false where the map holds no data.
  bool centre(int i, int j, Vec3& dir) const {
    if (!latlong_.cos_lat.empty()) {
      const LatLongMap::CentreAngles& a = latlong_;
      dir = Vec3(a.sin_lon[i] * a.cos_lat[j], a.sin_lat[j], a.cos_lon[i] * a.cos_lat[j]);
      return true;
    }
    return param_.to_direction(Vec2(i + 0.5, j + 0.5), dir);
  }

 private:
  const Parameterization& param_;
  LatLongMap::CentreAngles latlong_;  // empty unless param_ is a lat-long map
};

}  // namespace envkit
