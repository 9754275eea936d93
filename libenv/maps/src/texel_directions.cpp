#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>

namespace envkit {

TexelDirections::TexelDirections(const Parameterization& param) : param_(param) {
  if (const LatLongMap* latlong = param.latlong_geometry()) latlong_ = latlong->centre_angles();
}

}  // namespace envkit
