#include <envkit/maps/skylatlong.h>

#include <algorithm>
#include <cmath>

namespace envkit {

SkyLatLongMap::SkyLatLongMap(int width, int height)
    : Parameterization(width, height),
      sphere_(width, 2 * height),
      max_y_(std::nextafter(static_cast<double>(height), 0.0)) {}

std::string SkyLatLongMap::describe() const {
  return "skylatlong " + std::to_string(width_) + "x" + std::to_string(height_) +
         " (upper hemisphere, zenith on the top row, horizon on the bottom edge)";
}

bool SkyLatLongMap::to_direction(Vec2 pos, Vec3& dir) const {
  // Positions past the bottom edge would look below the horizon: they see the horizon, as a lat-long's clamp at
  // its poles.
  return sphere_.to_direction(Vec2(pos.x, std::min(pos.y, static_cast<double>(height_))), dir);
}

Vec2 SkyLatLongMap::to_image(const Vec3& dir) const {
  if (dir.y < 0.0) return Vec2(-1.0, -1.0);
  Vec2 p = sphere_.to_image(dir);
  p.y = std::min(p.y, max_y_);  // the horizon itself belongs to the bottom row
  return p;
}

double SkyLatLongMap::solid_angle(double x0, double y0, double x1, double y1) const {
  const double bottom = static_cast<double>(height_);
  return sphere_.solid_angle(x0, std::min(y0, bottom), x1, std::min(y1, bottom));
}

double SkyLatLongMap::solid_angle_density(Vec2 pos) const {
  return pos.y > height_ ? 0.0 : sphere_.solid_angle_density(pos);
}

bool SkyLatLongMap::resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const {
  if (j >= height_) return false;
  return sphere_.resolve_tap(anchor_i, anchor_j, i, j);
}

}  // namespace envkit
