#pragma once
/// @file texel_directions.h
/// Directions of texel centres (map frame), for loops that visit every texel of a map.
///
/// Lat-long maps are separable: the direction of texel (i, j) is (sin lon_i cos lat_j, sin lat_j, cos lon_i cos
/// lat_j), so one sin/cos table per column and per row replaces the trigonometry per texel (bit-identical to
/// LatLongMap::to_direction at the centre). Other maps call Parameterization::to_direction.
#include <envkit/parameterization.h>

#include <vector>

namespace envkit {

class TexelDirections {
 public:
  /// Keeps a reference to `param`, which must outlive this object.
  explicit TexelDirections(const Parameterization& param);

  /// Unit direction seen at the centre (i + 0.5, j + 0.5) of texel (i, j); false where the map holds no data.
  bool centre(int i, int j, Vec3& dir) const {
    if (!cos_lat_.empty()) {
      dir = Vec3(sin_lon_[i] * cos_lat_[j], sin_lat_[j], cos_lon_[i] * cos_lat_[j]);
      return true;
    }
    return param_.to_direction(Vec2(i + 0.5, j + 0.5), dir);
  }

 private:
  const Parameterization& param_;
  std::vector<double> sin_lon_, cos_lon_;  // per column (lat-long only)
  std::vector<double> sin_lat_, cos_lat_;  // per row (lat-long only)
};

}  // namespace envkit
