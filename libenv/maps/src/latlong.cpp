#include <envkit/maps/latlong.h>

#include <algorithm>
#include <cmath>

namespace envkit {

LatLongMap::LatLongMap(int width, int height, TexelGrid grid) : Parameterization(width, height), grid_(grid) {
  du_dx_ = 1.0 / (corner_columns() && width > 1 ? width - 1 : width);
  dv_dy_ = 1.0 / (corner_rows() && height > 1 ? height - 1 : height);
  max_x_ = std::nextafter(static_cast<double>(width), 0.0);
  max_y_ = std::nextafter(static_cast<double>(height), 0.0);
}

double LatLongMap::solid_angle_density(Vec2 pos) const {
  const double v = std::clamp(domain_from_image(pos).y, 0.0, 1.0);
  return kTwoPi * du_dx_ * kPi * dv_dy_ * std::sin(polar_angle(v));
}

bool LatLongMap::same_grid(const Parameterization& other) const {
  return same_kind_and_size(other) && static_cast<const LatLongMap&>(other).grid_ == grid_;
}

LatLongMap::CentreAngles LatLongMap::centre_angles() const {
  // The same expressions as direction_from_uv, evaluated once per column and per row.
  CentreAngles a;
  a.sin_lon.resize(std::size_t(width_));
  a.cos_lon.resize(std::size_t(width_));
  for (int i = 0; i < width_; ++i) {
    const double lon = longitude(domain_from_image(Vec2(i + 0.5, 0.5)).x);
    a.sin_lon[std::size_t(i)] = std::sin(lon);
    a.cos_lon[std::size_t(i)] = std::cos(lon);
  }
  a.sin_lat.resize(std::size_t(height_));
  a.cos_lat.resize(std::size_t(height_));
  for (int j = 0; j < height_; ++j) {
    const double lat = latitude(std::clamp(domain_from_image(Vec2(0.5, j + 0.5)).y, 0.0, 1.0));
    a.sin_lat[std::size_t(j)] = std::sin(lat);
    a.cos_lat[std::size_t(j)] = std::cos(lat);
  }
  return a;
}

std::vector<std::vector<std::size_t>> LatLongMap::twin_texels() const {
  // A corner grid's first and last columns both sit on the seam (u = 0 and u = 1 look along -Z). Its pole rows
  // are not grouped: each texel of a pole row keeps its own longitude's half-texel of the cap.
  if (grid_ != TexelGrid::Corner || width_ < 2) return {};
  const std::size_t W = std::size_t(width_);
  std::vector<std::vector<std::size_t>> groups(static_cast<std::size_t>(height_));
  for (std::size_t j = 0; j < groups.size(); ++j) groups[j] = {j * W, j * W + W - 1};
  return groups;
}

std::string LatLongMap::describe() const {
  return "latlong " + std::to_string(width_) + "x" + std::to_string(height_) +
         (grid_ == TexelGrid::Corner       ? ", corner-sampled (OpenEXR)"
          : grid_ == TexelGrid::CornerRows ? ", centre-sampled columns, corner-sampled rows (Mitsuba 3)"
                                           : ", centre-sampled");
}

Vec3 LatLongMap::direction_from_uv(double u, double v) {
  const double lat = latitude(v);
  const double lon = longitude(u);
  const double cos_lat = std::cos(lat);
  return Vec3(std::sin(lon) * cos_lat, std::sin(lat), std::cos(lon) * cos_lat);
}

double LatLongMap::u_from_direction(const Vec3& d, double horizontal) {
  const double lon = (horizontal == 0.0) ? 0.0 : std::atan2(d.x, d.z);
  double u = u_of_longitude(lon);
  if (u >= 1.0) u -= 1.0;
  if (u < 0.0) u = 0.0;
  return u;
}

Vec2 LatLongMap::uv_from_direction(const Vec3& d) {
  const double horizontal = std::hypot(d.x, d.z);
  const double lat = std::atan2(d.y, horizontal);  // accurate near the poles, unlike asin
  return Vec2(u_from_direction(d, horizontal), 0.5 - lat / kPi);
}

// Corner axis: texel centre i + 0.5 sits at u = i / (W - 1). A one-texel axis has no spacing to divide by:
// it is treated as centre-sampled, like OpenEXR, which maps it to longitude/latitude 0.
Vec2 LatLongMap::domain_from_image(Vec2 p) const {
  const double u = corner_columns() && width_ > 1 ? (p.x - 0.5) / (width_ - 1) : p.x / width_;
  const double v = corner_rows() && height_ > 1 ? (p.y - 0.5) / (height_ - 1) : p.y / height_;
  return Vec2(u, v);
}

Vec2 LatLongMap::image_from_domain(Vec2 uv) const {
  const double x = corner_columns() && width_ > 1 ? uv.x * (width_ - 1) + 0.5 : uv.x * width_;
  const double y = corner_rows() && height_ > 1 ? uv.y * (height_ - 1) + 0.5 : uv.y * height_;
  return Vec2(x, y);
}

bool LatLongMap::to_direction(Vec2 pos, Vec3& dir) const {
  const Vec2 uv = domain_from_image(pos);
  dir = direction_from_uv(uv.x, std::clamp(uv.y, 0.0, 1.0));
  return true;
}

Vec2 LatLongMap::to_image(const Vec3& dir) const {
  Vec2 p = image_from_domain(uv_from_direction(dir));
  // Keep the result inside the image: u = 1 - epsilon may round up to x = W.
  p.x = std::min(p.x, max_x_);
  p.y = std::clamp(p.y, 0.0, max_y_);
  return p;
}

double LatLongMap::solid_angle(double x0, double y0, double x1, double y1) const {
  Vec2 d0 = domain_from_image(Vec2(x0, y0));
  Vec2 d1 = domain_from_image(Vec2(x1, y1));
  // Corner grids: the half texels beyond the poles and beyond the duplicated seam hold no extra area.
  const double du = std::clamp(d1.x, 0.0, 1.0) - std::clamp(d0.x, 0.0, 1.0);
  const double v0 = std::clamp(d0.y, 0.0, 1.0), v1 = std::clamp(d1.y, 0.0, 1.0);
  if (du <= 0.0 || v1 <= v0) return 0.0;
  return kTwoPi * du * band_height(polar_angle(v0), polar_angle(v1));
}

bool LatLongMap::resolve_tap(int /*anchor_i*/, int /*anchor_j*/, int& i, int& j) const {
  // Longitude wraps with the period of the grid (a corner grid repeats column 0 as column W-1);
  // latitude clamps.
  const int period = (corner_columns() && width_ > 1) ? width_ - 1 : width_;
  i %= period;
  if (i < 0) i += period;
  j = std::clamp(j, 0, height_ - 1);
  return true;
}

}  // namespace envkit
