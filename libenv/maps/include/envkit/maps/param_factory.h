#pragma once
/// @file param_factory.h
/// Builds a parameterization from a kind, a size and a convention.
#include <envkit/maps/convention.h>
#include <envkit/maps/parameterization.h>
#include <envkit/maps/view.h>

#include <memory>
#include <optional>

namespace envkit {

struct ParamSpec {
  Kind kind = Kind::LatLong;
  int width = 0, height = 0;                      ///< image size in texels
  TexelGrid grid = TexelGrid::Centre;             ///< lat-long and cube only
  CubeLayout layout = CubeLayout::VerticalStrip;  ///< cube only
  CubeBasis basis = CubeBasis::Envkit;            ///< cube only
  /// Mirror-ball photographs: ball centre and radius in pixels (default: the inscribed circle).
  std::optional<double> ball_cx, ball_cy, ball_radius;
  /// Perspective and fisheye views: where they look, roll, field of view, lens.
  ViewParams view;
};

/// Throws Error when the size does not fit the kind (e.g. a cube layout whose faces are not square).
std::unique_ptr<Parameterization> make_parameterization(const ParamSpec& spec);

/// Image size of `kind` for the "natural size" N: lat-long and dual paraboloid 2N x N, sky lat-long 4N x N (the upper
/// half of a 4N x 2N lat-long), cube faces N x N laid out per `layout`, mirror ball, angular, sky angular, octahedral
/// and views N x N, HEALPix 4N x 3N (N = N_side).
void natural_image_size(Kind kind, int n, CubeLayout layout, int& width, int& height);

/// Spec for `kind` at natural size N with the grid, basis and layout of a convention.
ParamSpec spec_for(Kind kind, int n, const Convention& conv, std::optional<CubeLayout> layout = std::nullopt);

}  // namespace envkit
