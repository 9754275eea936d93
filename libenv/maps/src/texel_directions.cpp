#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>

namespace envkit {

TexelDirections::TexelDirections(const Parameterization& param) : param_(param) {
  if (const auto* latlong = dynamic_cast<const LatLongMap*>(&param)) latlong_ = latlong->centre_angles();
}

}  // namespace envkit
