#pragma once
/// @file sphere_pictures.h
/// envproduct's pictures of one shading point over the sphere of directions: BRDF x cos, the lighting and their
/// product, the samples of a strategy as dots over them, their density against the strategy's pdf, and the figure
/// that puts them side by side (the seed lecture's last figure, for any point).
///
/// Every picture is a lat-long of the scene's world frame (envkit's: +Y up, LatLongMap with texel centres at
/// ((x + 0.5) / W, (y + 0.5) / H)), the frame the normal, the view and the environment's rotation are given in,
/// so the lighting picture is the map as the scene sees it and the lobe sits where it reflects.
#include <envkit/core/image.h>
#include <envkit/maps/latlong.h>
#include <envkit/render/env_light.h>
#include <envkit/render/frame.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>

#include <cstdint>
#include <string>
#include <vector>

namespace envkit::render::cli {

/// The shading point pictured: its frame (frame.n the normal), the view in that frame, its material.
struct PointView {
  Frame frame;
  Vec3 wo_local;
  const Material* material = nullptr;
};

/// Linear RGB pictures at the texel centres: f(wo, wi) cos theta_i (eval(), 0 below the horizon), the
/// environment's radiance, and their texel-wise product.
struct SpherePictures {
  Image brdf_cos, lighting, product;
};
SpherePictures sphere_pictures(const LatLongMap& map, const PointView& point, const EnvironmentLight& light);

/// Directions StrategySamples keeps for the dots (a picture holds no more; the counts take every draw).
inline constexpr std::size_t kMaxDirections = 200000;

/// n draws of a strategy at the point (u from Owen-scrambled Sobol points of `seed`, sample i's first pair for the
/// direction and next dimension for the technique).
struct StrategySamples {
  std::vector<Vec3> directions;      ///< the first kMaxDirections drawn (delta draws included), world frame
  std::vector<double> texel_counts;  ///< non-delta draws per texel of the map, row-major
  std::size_t n = 0;                 ///< draws attempted
  std::size_t delta = 0;             ///< draws of a delta lobe (no density)
  std::size_t none = 0;              ///< draws that gave no direction (a BSDF sample below the horizon)
};
StrategySamples draw_samples(const Integrator::StrategyDistribution& strategy, const LatLongMap& map, std::size_t n,
                             std::uint32_t seed);

/// R: the samples' density per steradian (non-delta draws / (n x texel solid angle)); G: the strategy's pdf
/// averaged over the texel (at 4 x 4 sub-texels, each weighed by its solid angle: a piecewise-constant pdf whose cells
/// are not the texels' is integrated closely); B: 0. R converges to G as n grows.
Image density_picture(const LatLongMap& map, const StrategySamples& samples,
                      const Integrator::StrategyDistribution& strategy);

/// A linear picture made viewable: each texel's colour scaled so that its luminance Y becomes
/// log(1 + Y / mean Y) / log(1 + max Y / mean Y) (a sun does not blacken the sky, a lobe's tail stays visible).
Image display_picture(const Image& linear);
/// The display picture dimmed to 40%, with the directions as red dots (1 texel below 256 columns, then 2 x 2, 3 x 3
/// from 512, ...).
Image dotted_picture(const Image& display, const LatLongMap& map, const std::vector<Vec3>& directions);

/// A panel of the figure and its label.
struct Panel {
  const Image* image;
  std::string label;
};
/// The panels (one size) in rows of `columns`, each under a strip with its label (OIIO's render_text, the default
/// font, else DejaVu Sans). `labelled` receives false when no font could be found: the strips then stay empty.
Image compose_figure(const std::vector<Panel>& panels, int columns, bool* labelled);

}  // namespace envkit::render::cli
