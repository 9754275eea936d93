// envkit's HEALPix module: libhealpix-cxx behind detail::HealpixGeometry (libenv/maps/src/healpix_geometry.h), loaded
// by libenv on the first HEALPix map.
#include <healpix_cxx/healpix_base.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "healpix_geometry.h"

namespace envkit::detail {
namespace {

// libhealpix keeps its continuous face-coordinate map (xyf2loc) protected; a derived class may call it.
class ContinuousBase : public T_Healpix_Base<int64> {
 public:
  ContinuousBase(int64 nside, Healpix_Ordering_Scheme scheme) : T_Healpix_Base<int64>(nside, scheme, SET_NSIDE) {}
  ContinuousBase(int order, Healpix_Ordering_Scheme scheme) : T_Healpix_Base<int64>(order, scheme) {}
  vec3 face_point(double x, double y, int face) const {
    double z = 0.0, phi = 0.0, sth = 0.0;
    bool have_sth = false;
    xyf2loc(x, y, face, z, phi, sth, have_sth);
    const double s = have_sth ? sth : std::sqrt(std::max(0.0, (1.0 - z) * (1.0 + z)));
    return vec3(s * std::cos(phi), s * std::sin(phi), z);
  }
};

class Geometry final : public HealpixGeometry {
 public:
  explicit Geometry(int nside) : ring_(int64(nside), RING), fine_(kFineOrder, NEST) {
    if ((nside & (nside - 1)) == 0) nested_.emplace(int64(nside), NEST);
  }
  Vec3 face_point(double x, double y, int face) const override {
    const vec3 p = ring_.face_point(x, y, face);
    return Vec3(p.x, p.y, p.z);
  }
  void locate_fine(const Vec3& v, int& ix, int& iy, int& face) const override {
    fine_.pix2xyf(fine_.vec2pix(vec3(v.x, v.y, v.z)), ix, iy, face);
  }
  std::int64_t xyf2pix(int ix, int iy, int face, bool nested) const override {
    return (nested ? *nested_ : ring_).xyf2pix(ix, iy, face);
  }
  void pix2xyf(std::int64_t pixel, bool nested, int& ix, int& iy, int& face) const override {
    (nested ? *nested_ : ring_).pix2xyf(pixel, ix, iy, face);
  }
  bool has_nested() const override { return nested_.has_value(); }

 private:
  ContinuousBase ring_;                   // face_point (any scheme), RING indices
  std::optional<ContinuousBase> nested_;  // NESTED indices (power-of-two N_side only)
  ContinuousBase fine_;                   // direction -> continuous face coordinates
};

}  // namespace
}  // namespace envkit::detail

extern "C" __attribute__((visibility("default"))) envkit::detail::HealpixGeometry* envkit_healpix_geometry_v1(
    int nside) {
  return new envkit::detail::Geometry(nside);
}
