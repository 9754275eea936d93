#include <envkit/core/error.h>
#include <envkit/maps/healpix.h>

#include <algorithm>
#include <cmath>

#include "healpix_geometry.h"

namespace envkit {

namespace {

constexpr double kFineScale = double(std::int64_t(1) << detail::HealpixGeometry::kFineOrder);

}  // namespace

HealpixMap::HealpixMap(int nside) : Parameterization(4 * nside, 3 * nside), nside_(nside) {
  if (nside <= 0 || nside > (1 << 15))
    throw Error("HEALPix N_side must be in [1, 32768], not " + std::to_string(nside));
  geometry_ = detail::healpix_geometry(nside);
  tap_cell_ = nside;
}

std::string HealpixMap::describe() const {
  return "healpix N_side " + std::to_string(nside_) + " (" + std::to_string(width_) + "x" + std::to_string(height_) +
         ", 4x3 base pixels, equal-area)";
}

namespace {
// Cell (column, row) of base pixel f, and back.
int face_column(int face) { return 3 - face % 4; }
int face_row(int face) { return face / 4; }
int face_at_cell(int column, int row) { return 4 * row + (3 - column); }
}  // namespace

bool HealpixMap::to_direction(Vec2 pos, Vec3& dir) const {
  const double n = nside_;
  const int column = static_cast<int>(std::clamp(std::floor(pos.x / n), 0.0, 3.0));
  const int row = static_cast<int>(std::clamp(std::floor(pos.y / n), 0.0, 2.0));
  const double lx = std::clamp(pos.x - column * n, 0.0, n), ly = std::clamp(pos.y - row * n, 0.0, n);
  const Vec3 h = geometry_->face_point(1.0 - ly / n, lx / n, face_at_cell(column, row));
  dir = from_healpix_frame(h).normalized();
  return true;
}

Vec2 HealpixMap::to_image(const Vec3& dir) const {
  const Vec3 h = to_healpix_frame(dir);
  const double len = h.length();
  if (!(len > 0.0)) return Vec2(0.5, 0.5);
  int ix = 0, iy = 0, face = 0;
  geometry_->locate_fine(h / len, ix, iy, face);
  const double n = nside_;
  const double x = (ix + 0.5) / kFineScale, y = (iy + 0.5) / kFineScale;
  const double limit = std::nextafter(n, 0.0);
  const double lx = std::min(y * n, limit), ly = std::min((1.0 - x) * n, limit);
  return Vec2(face_column(face) * n + lx, face_row(face) * n + ly);
}

double HealpixMap::to_image_tolerance() const {
  // Half a fine pixel from its centre, doubled for the rounding of xyf2loc and vec2pix.
  return double(nside_) / kFineScale + 1e-9;
}

double HealpixMap::solid_angle(double x0, double y0, double x1, double y1) const {
  const double w = std::clamp(x1, 0.0, double(width_)) - std::clamp(x0, 0.0, double(width_));
  const double h = std::clamp(y1, 0.0, double(height_)) - std::clamp(y0, 0.0, double(height_));
  return (w > 0.0 && h > 0.0) ? pixel_solid_angle() * w * h : 0.0;
}

bool HealpixMap::resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const {
  const int n = nside_;
  const bool inside = i >= 0 && j >= 0 && i < width_ && j < height_;
  if (inside && i / n == anchor_i / n && j / n == anchor_j / n) return true;
  // Another base pixel: continue the anchor's local tangent plane across the
  // edge and find the texel that sees that direction (the cube map's
  // re-projection, with libhealpix deciding which face it falls on).
  const int ai = std::clamp(anchor_i, 0, width_ - 1), aj = std::clamp(anchor_j, 0, height_ - 1);
  Vec3 c, xm, xp, ym, yp;
  to_direction(Vec2(ai + 0.5, aj + 0.5), c);
  to_direction(Vec2(ai + 0.01, aj + 0.5), xm);
  to_direction(Vec2(ai + 0.99, aj + 0.5), xp);
  to_direction(Vec2(ai + 0.5, aj + 0.01), ym);
  to_direction(Vec2(ai + 0.5, aj + 0.99), yp);
  const Vec3 ex = (xp - xm) / 0.98, ey = (yp - ym) / 0.98;
  const Vec3 d = c + double(i - ai) * ex + double(j - aj) * ey;
  if (!(d.length() > 0.0)) return clamp_tap(i, j);
  const Vec2 p = to_image(d);
  i = std::clamp(static_cast<int>(p.x), 0, width_ - 1);
  j = std::clamp(static_cast<int>(p.y), 0, height_ - 1);
  return true;
}

void HealpixMap::texel_to_xyf(int i, int j, int& ix, int& iy, int& face) const {
  const int column = i / nside_, row = j / nside_;
  face = face_at_cell(column, row);
  iy = i - column * nside_;
  ix = nside_ - 1 - (j - row * nside_);
}

void HealpixMap::xyf_to_texel(int ix, int iy, int face, int& i, int& j) const {
  i = face_column(face) * nside_ + iy;
  j = face_row(face) * nside_ + (nside_ - 1 - ix);
}

std::int64_t HealpixMap::pixel_index(int i, int j, HealpixOrdering ordering) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_)
    throw Error("texel (" + std::to_string(i) + ", " + std::to_string(j) + ") is outside the HEALPix image");
  int ix = 0, iy = 0, face = 0;
  texel_to_xyf(i, j, ix, iy, face);
  const bool nested = ordering == HealpixOrdering::Nested;
  if (nested && !geometry_->has_nested())
    throw Error("NESTED ordering needs a power-of-two N_side, not " + std::to_string(nside_));
  return geometry_->xyf2pix(ix, iy, face, nested);
}

void HealpixMap::texel_of_pixel(std::int64_t pixel, HealpixOrdering ordering, int& i, int& j) const {
  if (pixel < 0 || pixel >= pixel_count())
    throw Error("HEALPix pixel " + std::to_string(pixel) + " is outside [0, " + std::to_string(pixel_count()) + ")");
  int ix = 0, iy = 0, face = 0;
  const bool nested = ordering == HealpixOrdering::Nested;
  if (nested && !geometry_->has_nested())
    throw Error("NESTED ordering needs a power-of-two N_side, not " + std::to_string(nside_));
  geometry_->pix2xyf(pixel, nested, ix, iy, face);
  xyf_to_texel(ix, iy, face, i, j);
}

}  // namespace envkit
