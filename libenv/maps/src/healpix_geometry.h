#pragma once
// What HealpixMap asks of Debian's libhealpix-cxx, in envkit's terms, so that the library lives in a module loaded on
// the first HEALPix map (libenvkit_healpix.so, libenv/maps/modules/healpix_geometry_module.cpp). libhealpix-cxx pulls
// in cfitsio, curl and GnuTLS, whose start-up alone cost every envkit program about 15 ms it mostly never needed.
//
// The module and libenv are built together by the same compiler, so C++ types cross the boundary; the entry point's
// name carries the interface version (kHealpixEntryPoint), and a module of another version is not found.
#include <envkit/core/vec.h>

#include <cstdint>
#include <memory>

namespace envkit::detail {

/// libhealpix's Healpix_Base objects for one N_side. Immutable; faces are HEALPix base pixels 0..11, in-face indices
/// (ix, iy) as libhealpix's xyf, vectors in the HEALPix frame (z up, phi from x towards y).
class HealpixGeometry {
 public:
  virtual ~HealpixGeometry() = default;
  /// Unit vector at continuous face coordinates (x, y) in [0, 1]^2 of base pixel `face` (libhealpix's xyf2loc).
  virtual Vec3 face_point(double x, double y, int face) const = 0;
  /// The finest NESTED pixel (order kFineOrder) holding unit vector `v`: its in-face indices and base pixel.
  virtual void locate_fine(const Vec3& v, int& ix, int& iy, int& face) const = 0;
  /// Pixel index of (ix, iy, face) in RING or NESTED order (NESTED only when has_nested()).
  virtual std::int64_t xyf2pix(int ix, int iy, int face, bool nested) const = 0;
  /// Inverse of xyf2pix.
  virtual void pix2xyf(std::int64_t pixel, bool nested, int& ix, int& iy, int& face) const = 0;
  /// NESTED indices exist: N_side is a power of two.
  virtual bool has_nested() const = 0;

  /// Order of locate_fine's pixels: its in-face indices divided by 2^29 are the continuous face coordinates of a
  /// direction to 2^-29 of a base pixel (about 2e-9 rad), the finest libhealpix has with 64-bit indices.
  static constexpr int kFineOrder = 29;
};

/// The module's entry point: extern "C" HealpixGeometry* envkit_healpix_geometry_v1(int nside), a new object the
/// caller owns (delete through the virtual destructor).
inline constexpr const char* kHealpixEntryPoint = "envkit_healpix_geometry_v1";

/// The geometry for N_side (1 <= nside <= 32768), loading the module on first call. Throws Error when the module
/// is unavailable.
std::shared_ptr<const HealpixGeometry> healpix_geometry(int nside);

}  // namespace envkit::detail
