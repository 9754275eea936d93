#pragma once
/// @file material_microfacet.h
/// Private helpers of the materials: isotropic GGX (Trowbridge-Reitz) distribution, Smith height-correlated
/// masking-shadowing, visible-normal sampling (Heitz 2018), Fresnel equations, cosine hemisphere sampling.
/// All directions in the local shading frame (z = normal). Every function is finite for every finite input.
#include <envkit/core/vec.h>
#include <envkit/render/material.h>

#include <algorithm>
#include <cmath>
#include <complex>

namespace envkit::render::detail {

/// Smallest GGX alpha: below it D's peak (1 / (pi alpha^2)) and its width stop being meaningful in double.
inline constexpr double kMinAlpha = 1e-3;

inline double clamp_alpha(double roughness) {
  return std::isfinite(roughness) ? std::clamp(roughness, kMinAlpha, 1.0) : 1.0;
}

/// GGX normal distribution D(m) for a unit half vector m (per steradian of m): alpha^2 / (pi (cos^2 (alpha^2 - 1)
/// + 1)^2). 0 below the horizon.
inline double ggx_d(double alpha, const Vec3& m) {
  if (!(m.z > 0.0)) return 0.0;
  const double a2 = alpha * alpha;
  const double t = m.z * m.z * (a2 - 1.0) + 1.0;  // >= a2 > 0 for a unit m
  return a2 / (kPi * t * t);
}

/// sqrt(alpha^2 + (1 - alpha^2) cos^2): the Smith Lambda term in the form that is finite at grazing angles
/// (Lambda(w) = (root / cos - 1) / 2).
inline double smith_root(double alpha, double cos_theta) {
  const double a2 = alpha * alpha;
  return std::sqrt(a2 + (1.0 - a2) * cos_theta * cos_theta);
}

/// Height-correlated Smith masking-shadowing times cos_i over the microfacet denominator:
/// G2 cos_i / (4 cos_o cos_i) = 0.5 / (cos_o root_i / cos_i + root_o) (Heitz 2014, eq. 99, rearranged so that it
/// stays finite, <= 0.5 / alpha, when both cosines are tiny or subnormal). Both cosines > 0.
inline double smith_g2_cos_over_4cos(double alpha, double cos_o, double cos_i) {
  const double denom = cos_o * smith_root(alpha, cos_i) / cos_i + smith_root(alpha, cos_o);
  return denom > 0.0 && std::isfinite(denom) ? 0.5 / denom : 0.0;
}

/// Separable Smith masking-shadowing G1(wo) G1(wi) (Cycles before Blender 4.0, OSL's microfacet closures) times
/// cos_i over the microfacet denominator: G1(o) G1(i) / (4 cos_o) = cos_i / ((cos_o + root_o) (cos_i + root_i)),
/// with G1(w) = 2 cos / (cos + root). Never above the height-correlated form (it counts the heights that mask and
/// shadow at once twice). Both cosines > 0.
inline double smith_g1g1_cos_over_4cos(double alpha, double cos_o, double cos_i) {
  const double denom = (cos_o + smith_root(alpha, cos_o)) * (cos_i + smith_root(alpha, cos_i));
  return denom > 0.0 && std::isfinite(denom) ? cos_i / denom : 0.0;
}

/// Density of wi = reflect(wo, h) under visible-normal sampling: G1(wo) D(h) / (4 cos_o)
/// = D(h) / (2 (cos_o + root_o)). cos_o > 0.
inline double vndf_reflection_pdf(double alpha, double cos_o, const Vec3& h) {
  return ggx_d(alpha, h) / (2.0 * (cos_o + smith_root(alpha, cos_o)));
}

/// Visible normal of GGX for wo (unit, wo.z > 0), Heitz 2018 listing 1, with u in [0,1)^2.
inline Vec3 sample_vndf(double alpha, const Vec3& wo, Vec2 u) {
  Vec3 vh(alpha * wo.x, alpha * wo.y, wo.z);
  vh.normalize();
  const double lensq = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = lensq > 0.0 ? Vec3(-vh.y, vh.x, 0.0) / std::sqrt(lensq) : Vec3(1.0, 0.0, 0.0);
  const Vec3 t2 = vh % t1;
  const double r = std::sqrt(std::clamp(u.x, 0.0, 1.0));
  const double phi = kTwoPi * u.y;
  const double p1 = r * std::cos(phi);
  double p2 = r * std::sin(phi);
  const double s = 0.5 * (1.0 + vh.z);
  p2 = (1.0 - s) * safe_sqrt(1.0 - p1 * p1) + s * p2;
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * safe_sqrt(1.0 - p1 * p1 - p2 * p2);
  Vec3 ne(alpha * nh.x, alpha * nh.y, std::max(0.0, nh.z));
  const double len = ne.length();
  return len > 0.0 ? ne / len : Vec3(0.0, 0.0, 1.0);
}

/// Mirror reflection of w about the unit vector m.
inline Vec3 reflect(const Vec3& w, const Vec3& m) { return m * (2.0 * (w ^ m)) - w; }

/// Unit half vector of wo and wi; false when they are opposite (or not finite).
inline bool half_vector(const Vec3& wo, const Vec3& wi, Vec3& h) {
  h = wo + wi;
  const double len2 = h.length2();
  if (!(len2 > 0.0) || !std::isfinite(len2)) return false;
  h /= std::sqrt(len2);
  return true;
}

/// Unpolarised Fresnel reflectance of a conductor with complex relative index eta + i k (outside medium 1), for
/// cos_i in [0, 1]: the exact equations in real arithmetic (pbrt-v3's FrConductor; 2 square roots, ~4x faster than
/// std::complex). eta = 0, k > 0 gives exactly 1 (up to round-off). Result clamped to [0, 1]; a singular index
/// (eta = k = 0) is a perfect reflector.
inline double fresnel_conductor(double cos_i, double eta, double k) {
  cos_i = std::clamp(cos_i, 0.0, 1.0);
  const double cos2 = cos_i * cos_i, sin2 = 1.0 - cos2;
  const double eta2 = eta * eta, k2 = k * k;
  const double t0 = eta2 - k2 - sin2;
  const double a2_plus_b2 = std::sqrt(t0 * t0 + 4.0 * eta2 * k2);
  const double t1 = a2_plus_b2 + cos2;
  const double a = safe_sqrt(0.5 * (a2_plus_b2 + t0));
  const double t2 = 2.0 * cos_i * a;
  const double rs = (t1 - t2) / (t1 + t2);
  const double t3 = cos2 * a2_plus_b2 + sin2 * sin2;
  const double t4 = t2 * sin2;
  const double rp = rs * (t3 - t4) / (t3 + t4);
  const double f = 0.5 * (rp + rs);
  return std::isfinite(f) ? std::clamp(f, 0.0, 1.0) : 1.0;
}

/// The same through std::complex (pbrt-v4's FrComplex): the reference the fast version is tested against.
inline double fresnel_conductor_complex(double cos_i, double eta, double k) {
  cos_i = std::clamp(cos_i, 0.0, 1.0);
  const std::complex<double> n(eta, k);
  const double sin2_i = 1.0 - cos_i * cos_i;
  const std::complex<double> sin2_t = sin2_i / (n * n);
  const std::complex<double> cos_t = std::sqrt(1.0 - sin2_t);
  const std::complex<double> r_parl = (n * cos_i - cos_t) / (n * cos_i + cos_t);
  const std::complex<double> r_perp = (cos_i - n * cos_t) / (cos_i + n * cos_t);
  const double f = 0.5 * (std::norm(r_parl) + std::norm(r_perp));
  return std::isfinite(f) ? std::clamp(f, 0.0, 1.0) : 1.0;
}

/// Unpolarised Fresnel reflectance of a dielectric interface seen from the outside (index 1 -> ior), cos_i in
/// [0, 1]. ior >= 1 (no total internal reflection from outside).
inline double fresnel_dielectric(double cos_i, double ior) {
  cos_i = std::clamp(cos_i, 0.0, 1.0);
  const double sin2_t = (1.0 - cos_i * cos_i) / (ior * ior);
  if (sin2_t >= 1.0) return 1.0;
  const double cos_t = std::sqrt(1.0 - sin2_t);
  const double r_parl = (ior * cos_i - cos_t) / (ior * cos_i + cos_t);
  const double r_perp = (cos_i - ior * cos_t) / (cos_i + ior * cos_t);
  const double f = 0.5 * (r_parl * r_parl + r_perp * r_perp);
  return std::isfinite(f) ? std::clamp(f, 0.0, 1.0) : 1.0;
}

/// Cosine-weighted hemisphere direction (Malley's method over Shirley-Chiu's concentric disk), u in [0,1)^2.
/// Density z / pi.
inline Vec3 sample_cosine_hemisphere(Vec2 u) {
  const double ox = 2.0 * u.x - 1.0, oy = 2.0 * u.y - 1.0;
  double r = 0.0, phi = 0.0;
  if (ox == 0.0 && oy == 0.0) return Vec3(0.0, 0.0, 1.0);
  if (std::abs(ox) > std::abs(oy)) {
    r = ox;
    phi = (kPi / 4.0) * (oy / ox);
  } else {
    r = oy;
    phi = kPi / 2.0 - (kPi / 4.0) * (ox / oy);
  }
  const double x = r * std::cos(phi), y = r * std::sin(phi);
  return Vec3(x, y, safe_sqrt(1.0 - x * x - y * y));
}

/// True when v is a finite direction strictly above the horizon.
inline bool above(const Vec3& v) { return v.z > 0.0 && std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// The sample of a material that reflects wo about the half vector h (local frame): wi with the material's own
/// f cos and pdf. False when wi falls below the horizon (out untouched: the sample is lost, and pdf() integrates to 1
/// minus that loss) or its pdf is 0.
inline bool reflection_sample(const Material& material, const Vec3& wo, const Vec3& h, BsdfSample& out) {
  const Vec3 wi = reflect(wo, h).normalized();
  if (!above(wi)) return false;
  out.wi = wi;
  out.f_cos = material.eval(wo, wi);
  out.pdf = material.pdf(wo, wi);
  out.is_delta = false;
  return out.pdf > 0.0;
}

/// The pdf of a GGX reflection lobe of roughness alpha drawn by visible-normal sampling (local frame; 0 below the
/// horizon): conductors and rough mirrors alike.
inline double ggx_reflection_pdf(double alpha, const Vec3& wo, const Vec3& wi) {
  Vec3 h;
  if (!above(wo) || !above(wi) || !half_vector(wo, wi, h)) return 0.0;
  return vndf_reflection_pdf(alpha, wo.z, h);
}

/// A visible-normal sample of a GGX reflection lobe of roughness alpha, valued by the material's own eval and pdf.
inline bool ggx_reflection_sample(const Material& material, double alpha, const Vec3& wo, Vec2 u2, BsdfSample& out) {
  if (!above(wo)) return false;
  return reflection_sample(material, wo, sample_vndf(alpha, wo, u2), out);
}

}  // namespace envkit::render::detail
