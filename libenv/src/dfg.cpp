#include <envkit/dfg.h>
#include <envkit/error.h>
#include <envkit/vec.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <utility>

namespace envkit {

std::string dfg_layout_name(DfgLayout layout) { return layout == DfgLayout::Filament ? "filament" : "scale-bias"; }

DfgLayout parse_dfg_layout(const std::string& name) {
  if (name == "scale-bias" || name == "karis" || name == "gltf") return DfgLayout::ScaleBias;
  if (name == "filament") return DfgLayout::Filament;
  throw Error("unknown DFG layout '" + name + "' (expected scale-bias or filament)");
}

namespace {

// Half vectors at polar angle (cos ct, sin st) whose reflection l = 2 (v.h) h -
// v lies above the horizon have azimuths |phi| <= the returned bound (v in the
// xz plane): n.l = 2 (v.h) ct - nv > 0 with v.h = sv st cos phi + nv ct.
// Integrating azimuth over exactly that range keeps the horizon's discontinuity
// out of the quadrature cells.
double azimuth_bound(double nv, double sv, double ct, double st) {
  if (st <= 0.0 || sv <= 0.0) return 2.0 * nv * ct * ct - nv > 0.0 ? kPi : 0.0;
  const double c0 = (nv / (2.0 * ct) - nv * ct) / (sv * st);
  return c0 <= -1.0 ? kPi : (c0 >= 1.0 ? 0.0 : std::acos(c0));
}

// The view's factor sqrt(nv^2 (1 - a^2) + a^2) of the height-correlated Smith term; it is the same for every light
// direction of one LUT texel, so the quadrature computes it once.
double smith_view_root(double nv, double a2) { return std::sqrt(nv * nv * (1.0 - a2) + a2); }

// Calls f(cos phi, weight x dphi) for the phi_samples azimuth midpoints of [-bound, bound], by mirror pairs: with
// v in the xz plane both integrands depend on the azimuth only through cos phi, so node p and node
// phi_samples - 1 - p add the same value and one evaluation with twice the weight stands for both (the middle node
// of an odd count once). Azimuths by rotation (angle addition) instead of a cos and a sin per node.
template <class F>
void for_azimuth_pairs(double bound, int phi_samples, F&& f) {
  const double dphi = 2.0 * bound / phi_samples;
  const int first = phi_samples / 2;
  const double phi0 = -bound + (first + 0.5) * dphi;
  double cp = std::cos(phi0), sp = std::sin(phi0);
  const double cd = std::cos(dphi), sd = std::sin(dphi);
  for (int p = first; p < phi_samples; ++p, std::tie(cp, sp) = std::pair(cp * cd - sp * sd, sp * cd + cp * sd))
    f(cp, (p == phi_samples - 1 - p ? 1.0 : 2.0) * dphi);
}

double smith_ggx_correlated(double nv, double view_root, double nl, double a2) {
  const double gv = nl * view_root;
  const double gl = nv * std::sqrt(nl * nl * (1.0 - a2) + a2);
  return 0.5 / (gv + gl);
}

}  // namespace

DfgValue dfg_integrate(double nv, double roughness, int theta_samples, int phi_samples) {
  nv = std::clamp(nv, 1e-4, 1.0);
  const Vec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);  // n = +z
  const double alpha = std::max(roughness * roughness, 1e-4);
  const double a2 = alpha * alpha;
  DfgValue out;
  // GGX: xi midpoints of the CDF of theta_h (tan^2 theta = a^2 xi / (1 - xi)),
  // h's measure D (n.h) d omega_h. Integral of D X d omega_l = E[X 4 (v.h) /
  // (n.h)] under that measure.
  double sa = 0.0, sb = 0.0;
  const double view_root = smith_view_root(nv, a2);
  // The substitution 1 - xi = s^2 (midpoints in s) absorbs the 1 / (n.h) ~ 1 /
  // sqrt(1 - xi) of grazing half vectors, which grazing views reflect above the
  // horizon; in xi itself the midpoint rule converges as 1 / sqrt(n).
  for (int t = 0; t < theta_samples; ++t) {
    const double sq = (t + 0.5) / theta_samples;
    const double xi = 1.0 - sq * sq, dxi = 2.0 * sq;
    const double cos2 = (1.0 - xi) / (1.0 + (a2 - 1.0) * xi);
    const double ct = std::sqrt(cos2), st = std::sqrt(std::max(0.0, 1.0 - cos2));
    const double bound = azimuth_bound(nv, v.x, ct, st);
    for_azimuth_pairs(bound, phi_samples, [&](double cp, double dphi) {
      const double vh = v.x * st * cp + v.z * ct;  // h = (st cos phi, st sin phi, ct)
      const double nl = 2.0 * vh * ct - nv;        // l = 2 (v.h) h - v
      if (nl <= 0.0 || vh <= 0.0) return;
      const double g = smith_ggx_correlated(nv, view_root, nl, a2) * nl * 4.0 * vh / ct;
      const double m = 1.0 - vh, m2 = m * m;
      const double fc = m2 * m2 * m;
      sa += g * (1.0 - fc) * dphi * dxi;
      sb += g * fc * dphi * dxi;
    });
  }
  out.scale = sa / (kTwoPi * theta_samples);
  out.bias = sb / (kTwoPi * theta_samples);
  // Charlie: midpoints in u = cos theta_h over [0, u_max], where sin^(1/a) has
  // decayed below e^-18.
  const double sheen_alpha = std::max(roughness * roughness, 1e-3);
  const double k = 1.0 / sheen_alpha;
  const double u_max = std::min(1.0, 6.0 / std::sqrt(k));
  const double norm = (2.0 + k) / kTwoPi;
  double ss = 0.0;
  for (int t = 0; t < theta_samples; ++t) {
    const double u = u_max * (t + 0.5) / theta_samples;
    const double s = std::sqrt(std::max(0.0, 1.0 - u * u));
    const double d = norm * std::pow(s, k);
    const double bound = azimuth_bound(nv, v.x, u, s);
    for_azimuth_pairs(bound, phi_samples, [&](double cp, double dphi) {
      const double vh = v.x * s * cp + v.z * u;  // h = (s cos phi, s sin phi, u)
      const double nl = 2.0 * vh * u - nv;
      if (nl <= 0.0 || vh <= 0.0) return;
      const double vis = 1.0 / (4.0 * (nl + nv - nl * nv));
      ss += d * vis * nl * 4.0 * vh * dphi;
    });
  }
  // d omega_h = du dphi over the upper hemisphere of h.
  out.sheen = ss * (u_max / theta_samples);
  return out;
}

Image dfg_lut(const DfgOptions& options) {
  if (options.width < 1 || options.height < 1) throw Error("DFG LUT: size must be at least 1 x 1");
  if (options.theta_samples < 1 || options.phi_samples < 1) throw Error("DFG LUT: sample counts must be positive");
  Image lut(options.width, options.height, 3);
  lut.channel_names = {"R", "G", "B"};
  tbb::parallel_for(0, options.height, [&](int j) {
    const double r = (j + 0.5) / options.height;
    for (int i = 0; i < options.width; ++i) {
      const DfgValue d = dfg_integrate((i + 0.5) / options.width, r, options.theta_samples, options.phi_samples);
      float* px = lut.at(i, j);
      if (options.layout == DfgLayout::Filament) {
        px[0] = float(d.bias);
        px[1] = float(d.albedo());
      } else {
        px[0] = float(d.scale);
        px[1] = float(d.bias);
      }
      px[2] = float(d.sheen);
    }
  });
  lut.metadata["envkit:dfg_layout"] = dfg_layout_name(options.layout);
  lut.metadata["envkit:dfg_axes"] =
      "x: n.v = (i+0.5)/width; y (row 0 first): "
      "perceptual roughness = (j+0.5)/height";
  lut.metadata["envkit:dfg_channels"] = options.layout == DfgLayout::Filament
                                            ? "R: bias B, G: albedo A+B, B: Charlie sheen"
                                            : "R: scale A, G: bias B, B: Charlie sheen";
  return lut;
}

}  // namespace envkit
