#include <envkit/core/error.h>
#include <envkit/core/gauss_legendre.h>
#include <envkit/core/vec.h>
#include <envkit/ibl/dfg.h>
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

// The same over [a, b] in the variable t = a + (b - a)(3x^2 - 2x^3): its flat ends turn an integrand that
// behaves like sqrt(distance to an end), as the visible azimuth range does at the horizon's kinks, into a smooth
// one in x.
template <class F>
void for_nodes_flat_ends(double a, double b, int n, F&& f) {
  if (!(b > a)) return;
  detail::for_nodes(0.0, 1.0, n, [&](double x, double w) {
    f(a + (b - a) * x * x * (3.0 - 2.0 * x), (b - a) * 6.0 * x * (1.0 - x) * w);
  });
}

// With v at polar angle theta_v (v in the xz plane), the reflection l = 2 (v.h) h - v of a half vector h at polar
// angle theta_h and azimuth phi is above the horizon, n.l = 2 (v.h) cos theta_h - n.v > 0, for every azimuth while
// theta_h < pi/4 - theta_v/2, for |phi| < acos(-(n.v / sin theta_v) cot(2 theta_h)) up to pi/4 + theta_v/2, and
// never beyond. Integrating each of these ranges separately keeps the horizon's kinks at the ends of the
// quadrature's intervals, where Gauss-Legendre loses nothing.
struct HorizonSplit {
  double full_below, none_above;  // theta_h bounds
};
HorizonSplit horizon_split(double nv) {
  const double theta_v = std::acos(nv);
  return {std::max(0.0, kPi / 4 - theta_v / 2), std::min(kPi / 2, kPi / 4 + theta_v / 2)};
}

// The azimuth bound |phi| of the visible reflections at half-vector polar angle (cos ct, sin st).
double azimuth_bound(double nv, double sv, double ct, double st) {
  if (st <= 0.0 || sv <= 0.0) return 2.0 * nv * ct * ct - nv > 0.0 ? kPi : 0.0;
  const double c0 = (nv / (2.0 * ct) - nv * ct) / (sv * st);
  return c0 <= -1.0 ? kPi : (c0 >= 1.0 ? 0.0 : std::acos(c0));
}

// The view's factor sqrt(nv^2 (1 - a^2) + a^2) of the height-correlated Smith term; it is the same for every light
// direction of one LUT texel, so the quadrature computes it once.
double smith_view_root(double nv, double a2) { return std::sqrt(nv * nv * (1.0 - a2) + a2); }

double smith_ggx_correlated(double nv, double view_root, double nl, double a2) {
  const double gv = nl * view_root;
  const double gl = nv * std::sqrt(nl * nl * (1.0 - a2) + a2);
  return 0.5 / (gv + gl);
}

}  // namespace

DfgValue dfg_integrate(double nv, double roughness, int theta_samples, int phi_samples) {
  nv = std::clamp(nv, 1e-4, 1.0);
  const double sv = std::sqrt(1.0 - nv * nv);  // v = (sv, 0, nv), n = +z
  const double alpha = std::max(roughness * roughness, 1e-4);
  const double a2 = alpha * alpha;
  const HorizonSplit split = horizon_split(nv);
  DfgValue out;
  // GGX: the variable s = sqrt(1 - xi), xi the CDF of theta_h under D (n.h) d omega_h (tan^2 theta = a^2 xi /
  // (1 - xi)); the integral of D X d omega_l is E[X 4 (v.h) / (n.h)] under that measure, and 1 - xi = s^2 absorbs
  // the 1 / (n.h) ~ 1 / sqrt(1 - xi) of grazing half vectors, which grazing views reflect above the horizon.
  // s falls as theta_h grows: s(theta) = a cos theta / sqrt(sin^2 theta + a^2 cos^2 theta).
  auto s_of = [&](double theta) {
    const double c = std::cos(theta), sn = std::sin(theta);
    return alpha * c / std::sqrt(sn * sn + a2 * c * c);
  };
  const double view_root = smith_view_root(nv, a2);
  double sa = 0.0, sb = 0.0;
  // Both integrands depend on the azimuth only through cos phi (v in the xz plane): twice the integral over
  // [0, bound].
  auto ggx_at = [&](double s, double ds) {
    const double xi = 1.0 - s * s, dxi = 2.0 * s * ds;
    const double cos2 = (1.0 - xi) / (1.0 + (a2 - 1.0) * xi);
    const double ct = std::sqrt(cos2), st = std::sqrt(std::max(0.0, 1.0 - cos2));
    double a_sum = 0.0, b_sum = 0.0;
    detail::for_nodes(0.0, azimuth_bound(nv, sv, ct, st), phi_samples, [&](double phi, double w) {
      const double vh = sv * st * std::cos(phi) + nv * ct;  // h = (st cos phi, st sin phi, ct)
      const double nl = 2.0 * vh * ct - nv;                 // l = 2 (v.h) h - v
      if (nl <= 0.0 || vh <= 0.0) return;
      const double g = w * smith_ggx_correlated(nv, view_root, nl, a2) * nl * 4.0 * vh / ct;
      const double m = 1.0 - vh, m2 = m * m;
      const double fc = m2 * m2 * m;
      a_sum += g * (1.0 - fc);
      b_sum += g * fc;
    });
    sa += 2.0 * a_sum * dxi;
    sb += 2.0 * b_sum * dxi;
  };
  const double s_full = s_of(split.full_below), s_none = s_of(split.none_above);
  detail::for_nodes(s_full, 1.0, theta_samples, ggx_at);
  for_nodes_flat_ends(s_none, s_full, theta_samples, ggx_at);
  out.scale = sa / kTwoPi;
  out.bias = sb / kTwoPi;
  // Charlie: u = cos theta_h over [0, u_max], where sin^(1/a) has decayed below e^-18, split like the GGX lobe.
  const double sheen_alpha = std::max(roughness * roughness, 1e-3);
  const double k = 1.0 / sheen_alpha;
  const double u_max = std::min(1.0, 6.0 / std::sqrt(k));
  const double norm = (2.0 + k) / kTwoPi;
  double ss = 0.0;
  auto charlie_at = [&](double u, double du) {
    const double s = std::sqrt(std::max(0.0, 1.0 - u * u));
    const double d = norm * std::pow(s, k);
    double sum = 0.0;
    detail::for_nodes(0.0, azimuth_bound(nv, sv, u, s), phi_samples, [&](double phi, double w) {
      const double vh = sv * s * std::cos(phi) + nv * u;  // h = (s cos phi, s sin phi, u)
      const double nl = 2.0 * vh * u - nv;
      if (nl <= 0.0 || vh <= 0.0) return;
      sum += w * nl * 4.0 * vh / (4.0 * (nl + nv - nl * nv));
    });
    ss += 2.0 * du * d * sum;
  };
  const double u_full = std::cos(split.full_below), u_none = std::cos(split.none_above);
  for_nodes_flat_ends(std::max(u_none, 0.0), std::min(u_full, u_max), theta_samples, charlie_at);
  detail::for_nodes(std::max(u_full, 0.0), u_max, theta_samples, charlie_at);
  // d omega_h = du dphi over the upper hemisphere of h.
  out.sheen = ss;
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
