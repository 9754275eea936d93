#include <envkit/core/error.h>
#include <envkit/maps/angular.h>
#include <envkit/maps/fisheye.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/perspective.h>
#include <envkit/maps/skyangular.h>
#include <envkit/maps/skylatlong.h>

namespace envkit {

std::unique_ptr<Parameterization> make_parameterization(const ParamSpec& s) {
  if (s.width <= 0 || s.height <= 0)
    throw Error("image size " + std::to_string(s.width) + "x" + std::to_string(s.height) + " is empty");
  const std::string size = std::to_string(s.width) + "x" + std::to_string(s.height);
  switch (s.kind) {
    case Kind::LatLong:
      return std::make_unique<LatLongMap>(s.width, s.height, s.grid);
    case Kind::MirrorBall:
      if (s.ball_cx || s.ball_cy || s.ball_radius)
        return std::make_unique<MirrorBallMap>(s.width, s.height, s.ball_cx.value_or(0.5 * s.width),
                                               s.ball_cy.value_or(0.5 * s.height),
                                               s.ball_radius.value_or(0.5 * std::min(s.width, s.height)));
      return std::make_unique<MirrorBallMap>(s.width, s.height);
    case Kind::AngularMap:
      return std::make_unique<AngularMap>(s.width, s.height);
    case Kind::CubeMap: {
      const int n = face_size_for(s.layout, s.width, s.height);
      if (n == 0) throw Error("size " + size + " does not fit a cube map laid out as " + layout_name(s.layout));
      return std::make_unique<CubeMap>(n, s.layout, s.basis, s.grid);
    }
    case Kind::Octahedral:
      if (s.width != s.height) throw Error("an octahedral map must be square, not " + size);
      return std::make_unique<OctahedralMap>(s.width);
    case Kind::DualParaboloid:
      return std::make_unique<DualParaboloidMap>(s.width, s.height);
    case Kind::HEALPix:
      if (s.width % 4 != 0 || s.width * 3 != s.height * 4)
        throw Error("a HEALPix image is 4 N_side x 3 N_side (twelve base pixels), not " + size);
      return std::make_unique<HealpixMap>(s.width / 4);
    case Kind::Perspective:
      return std::make_unique<PerspectiveMap>(s.width, s.height, s.view);
    case Kind::Fisheye:
      return std::make_unique<FisheyeMap>(s.width, s.height, s.view);
    case Kind::SkyLatLong:
      return std::make_unique<SkyLatLongMap>(s.width, s.height);
    case Kind::SkyAngular:
      return std::make_unique<SkyAngularMap>(s.width, s.height);
  }
  throw Error("unknown parameterization");
}

void natural_image_size(Kind kind, int n, CubeLayout layout, int& width, int& height) {
  switch (kind) {
    case Kind::LatLong:
    case Kind::DualParaboloid:
      width = 2 * n;
      height = n;
      return;
    case Kind::SkyLatLong:
      width = 4 * n;
      height = n;
      return;
    case Kind::CubeMap:
      layout_size(layout, n, width, height);
      return;
    case Kind::HEALPix:
      width = 4 * n;
      height = 3 * n;
      return;
    default:
      width = n;
      height = n;
      return;
  }
}

ParamSpec spec_for(Kind kind, int n, const Convention& conv, std::optional<CubeLayout> layout) {
  ParamSpec s;
  s.kind = kind;
  s.layout = layout.value_or(conv.cube_layout);
  s.basis = conv.cube_basis;
  s.grid = kind == Kind::LatLong ? conv.latlong_grid : (kind == Kind::CubeMap ? conv.cube_grid : TexelGrid::Centre);
  natural_image_size(kind, n, s.layout, s.width, s.height);
  return s;
}

}  // namespace envkit
