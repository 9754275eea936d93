#pragma once
/// @file sh.h
/// Real spherical harmonics of an environment: radiance coefficients and the
/// diffuse irradiance they give (Ramamoorthi and Hanrahan 2001), for real-time
/// engines.
///
/// Basis (core/sh_basis.h, any order): real, orthonormal over the sphere
/// (integral of Y_i Y_j d omega = delta_ij), WITHOUT the Condon-Shortley
/// phase, index i = l (l + 1) + m, written in the world-frame components
/// (x, y, z) of the unit direction (envkit and GL: +Y up; the polynomials use
/// z as their axis, as in Ramamoorthi-Hanrahan and Sloan). Up to band 3:
///   l=0: 0.282095
///   l=1: 0.488603 y, 0.488603 z, 0.488603 x
///   l=2: 1.092548 xy, 1.092548 yz, 0.315392 (3z^2 - 1), 1.092548 xz, 0.546274
///   (x^2 - y^2) l=3: 0.590044 y (3x^2 - y^2), 2.890611 xyz, 0.457046 y (4z^2 -
///   x^2 - y^2), 0.373176 z (2z^2 - 3x^2 - 3y^2),
///        0.457046 x (4z^2 - x^2 - y^2), 1.445306 z (x^2 - y^2), 0.590044 x
///        (x^2 - 3y^2)
///
/// Radiance coefficients: L_lm = sum over texels of L Y_lm(centre) x exact
/// texel solid angle (double sums). Irradiance: E(n) = sum A_l w_l L_lm Y_lm(n)
/// with the clamped-cosine convolution A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4,
/// A_3 = 0 (every odd l > 1 vanishes), A_4 = -pi / 24, ..., w_l the optional
/// window. Dividing by pi
/// gives the outgoing radiance of a white Lambertian surface (the BRDF's 1/pi
/// folded in), what engines multiply by the albedo.
///
/// Windowing against ringing under a sun (Sloan, "Stupid Spherical Harmonics
/// (SH) Tricks", 2008), window width w = order + 1: Hanning w_l = (1 + cos(pi l
/// / w)) / 2; Lanczos w_l = sinc(pi l / w) = sin(pi l / w) / (pi l / w). The
/// window multiplies the coefficients of band l; the unwindowed radiance
/// coefficients are kept too.
#include <envkit/core/sh_basis.h>
#include <envkit/resample/resample.h>

#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace envkit {

enum class ShWindow { None, Hanning, Lanczos };
std::string sh_window_name(ShWindow window);
/// "none", "hanning" (also "hann"), "lanczos". Throws Error.
ShWindow parse_sh_window(const std::string& name);

/// Clamped-cosine convolution factor A_l (pi, 2 pi / 3, pi / 4, 0 for l = 3, -pi / 24, 0, pi / 64, ...; every
/// odd l > 1 is 0).
double sh_cosine_lobe(int l);
/// Window factor of band l for a window of width order + 1.
double sh_window_factor(ShWindow window, int l, int order);

struct ShCoefficients {
  int order = 2;
  ShWindow window = ShWindow::None;
  std::vector<std::string> channel_names;     ///< colour channels (alpha is not projected)
  std::vector<std::vector<double>> radiance;  ///< [channel][i]: L_lm, unwindowed
  /// E(n) = sum irradiance[c][i] Y_i(n): A_l w_l L_lm.
  std::vector<std::vector<double>> irradiance() const;
  /// irradiance() / pi: E(n) / pi, the radiance a white Lambertian surface reflects (the JSON's
  /// irradiance_over_pi).
  std::vector<std::vector<double>> irradiance_over_pi() const;
  /// E(n) / pi for channel c at direction n (world frame).
  double eval_irradiance(int channel, const Vec3& n) const;
  /// The radiance the (unwindowed) coefficients reconstruct for channel c at direction n (world frame):
  /// sum L_lm Y_lm(n).
  double eval_radiance(int channel, const Vec3& n) const;
  /// The coefficients as JSON with the normalisation spelled out (see
  /// docs/PREFILTER.md).
  nlohmann::json to_json() const;
};

/// Projects the colour channels of `src` (world frame) onto SH up to `order`
/// (1 .. kMaxShOrder). Deterministic and independent of the thread count.
ShCoefficients project_sh(const MapRef& src, int order = 2, ShWindow window = ShWindow::None);

}  // namespace envkit
