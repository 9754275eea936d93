#pragma once
/// @file dfg.h
/// The split-sum DFG lookup table for real-time image-based lighting (Karis
/// 2013; Filament's multiple-scattering layout; the Charlie sheen lobe of
/// KHR_materials_sheen).
///
/// Texel (i, j), row 0 first: n.v = (i + 0.5) / width, perceptual roughness r =
/// (j + 0.5) / height, GGX alpha = r^2. With v at angle acos(n.v) from n, F_c =
/// (1 - v.h)^5 and the Smith height-correlated visibility V = 0.5 / (n.v
/// sqrt((n.l)^2 (1 - a^2) + a^2) + n.l sqrt((n.v)^2 (1 - a^2) + a^2)) (= G / (4
/// n.l n.v)):
///   scale A = integral of D V (1 - F_c) n.l d omega_l,   bias B = integral of
///   D V F_c n.l d omega_l,
/// so that the specular IBL is prefiltered(r) x (F0 A + F90 B). E = A + B is
/// the single-scattering directional albedo for F = 1; the multiple-scattering
/// energy compensation (Fdez-Aguera 2019, Filament) multiplies the specular by
/// 1 + F0 (1 / E - 1). Sheen (Charlie, Estevez and Kulla 2017): D_c = (2 + 1/a)
/// sin(theta_h)^(1/a) / (2 pi) with a = r^2 clamped to
/// >= 1e-3, visibility V_n = 1 / (4 (n.l + n.v - n.l n.v)) (Neubelt and
/// Pettineo 2013, Filament's IBL sheen):
///   S = integral of D_c V_n n.l d omega_l.
/// Integration: deterministic product quadrature over the half vector h (GGX:
/// the variable sqrt(1 - the GGX CDF) of theta_h; Charlie: cos theta_h over
/// the lobe's support; both times the azimuth over exactly the range whose
/// reflection lies above the horizon). theta_h is cut where that range stops
/// being the whole circle and where it vanishes, and each piece, and the
/// azimuth range, is integrated by Gauss-Legendre (the piece between the cuts
/// through a variable with flat ends, which smooths the range's square-root
/// behaviour there): with the default 20 x 8 nodes every texel of the 128^2
/// LUT is within 1e-4 of 128 x 64 nodes, and the whole agrees with an
/// independent integration over the light direction to 1e-3
/// (tests/ibl/test_prefilter_dfg.cpp).
#include <envkit/core/image.h>

#include <string>
#include <vector>

namespace envkit {

/// Channel layouts of the written LUT.
enum class DfgLayout {
  /// R = A (scale of F0), G = B (bias), B = S (sheen): Karis /
  /// glTF-Sample-Viewer (its sheen LUT is separate).
  ScaleBias,
  /// R = B, G = A + B = E, B = S: Filament's multiple-scattering layout
  /// (specular = mix(R, G, F0), energy
  /// compensation 1 + F0 (1 / G - 1)).
  Filament,
};
std::string dfg_layout_name(DfgLayout layout);
DfgLayout parse_dfg_layout(const std::string& name);  ///< "scale-bias" (also "karis", "gltf"), "filament"

struct DfgOptions {
  int width = 128;         ///< n.v samples
  int height = 128;        ///< roughness samples
  int theta_samples = 20;  ///< Gauss-Legendre nodes per interval of theta_h
  int phi_samples = 8;     ///< Gauss-Legendre nodes over the visible half-range of azimuth
  DfgLayout layout = DfgLayout::ScaleBias;
};

/// The three integrals at one (n.v, perceptual roughness).
struct DfgValue {
  double scale = 0.0, bias = 0.0, sheen = 0.0;
  double albedo() const { return scale + bias; }
  /// 1 + F0 (1 / E - 1) factor's 1 / E - 1 (0 when E = 0).
  double energy_compensation() const { return albedo() > 0.0 ? 1.0 / albedo() - 1.0 : 0.0; }
};
DfgValue dfg_integrate(double n_dot_v, double roughness, int theta_samples = 20, int phi_samples = 8);

/// The LUT as a 3-channel float image (channels per DfgLayout, named R, G, B),
/// metadata envkit:dfg_layout and envkit:dfg_axes. Parallel; independent of the
/// thread count.
Image dfg_lut(const DfgOptions& options = {});

}  // namespace envkit
