#pragma once
/// @file healpix.h
/// HEALPix (Gorski et al. 2005) as an image: 12 N_side^2 pixels of equal solid
/// angle 4 pi / (12 N_side^2), centres on iso-latitude rings. The pixel
/// geometry is Debian's libhealpix-cxx (Healpix_Base: xyf2loc, vec2pix,
/// pix2xyf, xyf2pix, RING and NESTED), in a module loaded on the first
/// HEALPix map (constructing one throws Error when the module is missing;
/// ENVKIT_HEALPIX_MODULE names another copy); this class adds the image layout, the
/// texel <-> direction maps of the Parameterization interface, exact
/// sub-rectangle solid angles and filter taps across base-pixel edges.
///
/// Image layout ("4x3 base-pixel grid"): a 4 N x 3 N image of twelve N x N
/// cells, one per HEALPix base pixel f (face number as in libhealpix/healpy:
/// 0-3 north polar, 4-7 equatorial, 8-11 south polar). Row r = f / 4 of cells
/// holds the north faces (top), the equatorial faces (middle) and the south
/// faces (bottom); within a row the column is 3 - f % 4, so longitude grows to
/// the left as on a lat-long seen from inside. Inside a cell, texel (i, j) of
/// the cell is HEALPix pixel (ix, iy, f) with ix = N - 1 - j (ix grows upwards,
/// towards the face's north-east edge) and iy = i (iy grows to the right,
/// towards its north-west edge): each base pixel is its HEALPix-projection
/// diamond rotated by 45 degrees into a square, its north vertex at the top
/// right. Every texel is exactly one HEALPix pixel; none is blank. Continuous
/// positions map linearly to libhealpix's face coordinates (x, y) = (ix, iy) /
/// N, and the HEALPix projection is equal-area in them, so the solid angle of
/// any sub-rectangle is its area times 4 pi / (12 N^2).
///
/// Frame: HEALPix's z axis (theta = 0) is envkit's up axis +Y and phi = 0 looks
/// along +Z, phi = pi/2 along +X: HEALPix (x_h, y_h, z_h) = envkit (Z, X, Y), a
/// proper rotation, so phi is the longitude of envkit's lat-long (lat-long u =
/// 1/2 - phi / (2 pi)) and theta its polar angle.
///
/// Images of this layout are 4:3 like a horizontal-cross cube: they are
/// recognised from envkit metadata or --from healpix, never from the aspect
/// ratio.
#include <envkit/maps/parameterization.h>

#include <cstdint>
#include <memory>

namespace envkit {

namespace detail {
class HealpixGeometry;  // libhealpix behind an interface (the module's)
}

enum class HealpixOrdering { Ring, Nested };

class HealpixMap final : public Parameterization {
 public:
  /// N_side >= 1 (any value; NESTED indices need a power of two). Image 4
  /// N_side x 3 N_side.
  explicit HealpixMap(int nside);

  Kind kind() const override { return Kind::HEALPix; }
  std::string describe() const override;
  /// The layout is fixed by N_side, so the size says it all.
  bool same_grid(const Parameterization& other) const override { return same_kind_and_size(other); }
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<HealpixMap>(*this); }

  int nside() const { return nside_; }
  /// 12 N_side^2.
  std::int64_t pixel_count() const { return 12 * std::int64_t(nside_) * nside_; }
  /// 4 pi / (12 N_side^2), steradians: every texel's solid angle.
  double pixel_solid_angle() const { return kFourPi / double(pixel_count()); }

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  Vec2 to_image(const Vec3& dir) const override;
  /// Texels: to_image(d) lies within this distance (per axis) of the position to_direction mapped to d. It
  /// locates directions through libhealpix's finest NESTED pixels (2^-29 of a base pixel), so a direction closer
  /// than this to a texel edge may be placed in the neighbouring texel.
  double to_image_tolerance() const;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2) const override { return pixel_solid_angle(); }
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

  /// HEALPix pixel index of texel (i, j) (inside the image) in `ordering`.
  /// Throws Error for NESTED when N_side is not a power of two.
  std::int64_t pixel_index(int i, int j, HealpixOrdering ordering) const;
  /// Texel holding HEALPix pixel `pixel` (0 <= pixel < pixel_count()) of
  /// `ordering`.
  void texel_of_pixel(std::int64_t pixel, HealpixOrdering ordering, int& i, int& j) const;
  /// Base pixel (face 0..11) and in-face indices (ix, iy) of texel (i, j).
  void texel_to_xyf(int i, int j, int& ix, int& iy, int& face) const;
  void xyf_to_texel(int ix, int iy, int face, int& i, int& j) const;

  /// envkit direction -> HEALPix frame (x_h, y_h, z_h) = (Z, X, Y), and back.
  static Vec3 to_healpix_frame(const Vec3& d) { return Vec3(d.z, d.x, d.y); }
  static Vec3 from_healpix_frame(const Vec3& h) { return Vec3(h.y, h.z, h.x); }

 private:
  int nside_;
  std::shared_ptr<const detail::HealpixGeometry> geometry_;  // shared by copies (immutable)
};

}  // namespace envkit
