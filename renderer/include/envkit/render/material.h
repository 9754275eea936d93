#pragma once
/// @file material.h
/// The renderer's materials (BSDFs): Lambertian diffuse, rough conductor, rough plastic, perfect mirror.
///
/// Conventions
/// -----------
/// - Every direction is a unit vector in the LOCAL shading frame (frame.h): z is the shading normal, so
///   cos theta = z. wo points from the surface toward the viewer, wi toward the light. Both point away from the
///   surface.
/// - Materials are one-sided reflectors: anything with wo.z <= 0 or wi.z <= 0 is black (eval 0, pdf 0,
///   sample false). The integrator flips the shading frame to the side of wo for two-sided surfaces.
/// - eval() returns f(wo, wi) max(cos theta_i, 0) in RGB (linear, per steradian x cos), without delta lobes.
/// - pdf() is the solid-angle density with which sample() draws wi (its non-delta part), normalised over the
///   sphere; it integrates to <= 1 (microfacet samples that reflect below the horizon are lost: sample() returns
///   false for them, so pdf() integrates to 1 minus that loss).
/// - sample() fills f_cos = eval(wo, wi) and pdf = pdf(wo, wi) for non-delta samples (so f_cos / pdf is the
///   estimator weight); for a delta lobe f_cos is the lobe's weight (the Dirac's coefficient) and pdf the
///   probability of choosing the lobe (1 for a pure mirror).
/// - No NaN or inf ever leaves a function: grazing and below-horizon directions give 0 / false.
///
/// Models (stated in full: matching another renderer needs the exact formulas)
/// ----------------------------------------------------------------------------
/// - diffuse: f = albedo / pi; cosine-weighted hemisphere sampling (Shirley-Chiu concentric disk, Malley).
/// - conductor: GGX (Trowbridge-Reitz) microfacet reflection, isotropic, alpha = roughness (clamped to
///   [1e-3, 1]); Smith HEIGHT-CORRELATED masking-shadowing G2 = 1 / (1 + Lambda(wo) + Lambda(wi)) (or, on request,
///   the separable G1(wo) G1(wi) of renderers that use it: Shadowing below); exact conductor
///   Fresnel for the complex index eta + i k per RGB channel (outside medium index 1); sampling: the distribution
///   of visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"), pdf(wi) =
///   G1(wo) D(h) / (4 cos theta_o). eta = 0 with any k > 0 gives F = 1 exactly (a white conductor).
/// - plastic: a GGX dielectric coat (same D and G2, dielectric Fresnel for ior) over a Lambertian base, the
///   Fresnel-weighted layering of Mitsuba's roughplastic (nonlinear variant):
///     f = F(wo.h) D G2 / (4 cos_o cos_i)
///       + diffuse (1 - F(cos_o)) (1 - F(cos_i)) / (pi ior^2 (1 - diffuse Fdr_int))
///   with Fdr_int = 1 - (1 - Fdr_ext) / ior^2 the hemispherical internal reflectance of the smooth coat
///   (Fdr_ext integrated numerically). Reciprocal; the diffuse part alone has albedo <= 1 - F(cos_o).
///   Sampling: one lobe chosen with u_lobe, specular with probability F(cos_o) / (F(cos_o) + (1 - F(cos_o))
///   mean(diffuse)) (the estimated albedos), pdf = the mixture pdf.
/// - mirror: a delta lobe wi = (-wo.x, -wo.y, wo.z) with constant reflectance (no Fresnel). With a roughness floor
///   (with_roughness_floor()): f = reflectance D G2 / (4 cos_o cos_i), GGX of the floor's alpha, height-correlated
///   G2, no Fresnel, visible-normal sampling (a white conductor's lobe scaled by the reflectance).
/// - measured: an isotropic BRDF read from a MERL binary file (Matusik et al. 2003; format and cells: merl.h in
///   renderer/src, docs/SCENE_FORMAT.md). f is interpolated TRILINEARLY between the cells' centres in the
///   format's own coordinates (sqrt(theta_half) index, theta_diff, phi_diff; clamped at the ends of the theta axes,
///   periodic with period pi in phi_diff), so it is continuous (the reference code's nearest lookup makes steps in
///   highlights) and exact at the centres. A cell with a negative (missing) value in any channel is black: the
///   measurement misses cells near grazing theta_diff, where cos theta_i is small. Reciprocal by construction.
///   Sampling by tabulated inversion over half vectors h (wi = reflect(wo, h), d omega_i = 4 (wo.h) d omega_h):
///   32 theta_o bins (uniform in theta_o; wo's bin is the one containing its theta_o, for sample() and pdf()
///   alike), each a CdfDistribution2D over 90 x 128 half-vector cells (theta_half = (pi/2) v^2 for v uniform over
///   the 90 rows, as the format's own axis; phi_half - phi_o uniform over [0, 2 pi)) holding the mass of f cos
///   (mean of RGB) at the bin's centre (2x2 midpoint rule per cell) plus 0.1% spread uniformly over the half
///   vectors' solid angle (so the density is positive wherever f is). Inside a cell, h is uniform in solid angle;
///   pdf = P(cell) / (solid angle of the cell) / (4 wo.h). Half vectors that reflect wo below the horizon are
///   lost (sample() false). Memory: the data 90 x 90 x 180 x 3 floats = 17.5 MB, the tables ~1.5 MB (32 x ~47 KB);
///   built once at load (bins in parallel with oneTBB), immutable afterwards.
///   Lobe alphas (the product tables' proxies), from the data at normal incidence: the share of f cos per
///   theta_half (f cos_i 4 cos theta_half sin theta_half over theta_half < pi/4) has quantiles that a GGX lobe
///   (D cos theta_half, cut at the horizon) of alpha = tan t sqrt((1 - q) / (q - tan^2 t)) shares; the narrowest
///   lobe takes the alpha of the 5% quantile, the widest that of the median (never less than the narrowest);
///   an alpha of 0.5 or more (a Lambertian lobe reads 0.51-0.57) is reported as 1. narrowest_lobe_probability()
///   is 1/2 when the two differ (one sampler draws both). Any positive proxy keeps MIS unbiased.
#include <envkit/core/vec.h>

#include <memory>
#include <string>

namespace envkit::render {

struct BsdfSample {
  Vec3 wi;         // sampled incident direction, LOCAL shading frame (z = shading normal), unit
  Vec3 f_cos;      // f(wo, wi) * |cos theta_i| (RGB); for a delta lobe: the lobe's weight times the Dirac
  double pdf = 0;  // solid-angle pdf of wi; for a delta lobe: the probability of choosing the lobe
  bool is_delta = false;
};

class Material {
 public:
  virtual ~Material() = default;
  virtual const char* name() const = 0;
  /// f(wo, wi) * max(cos theta_i, 0), local frame, non-delta part only. wo points toward the viewer.
  virtual Vec3 eval(const Vec3& wo, const Vec3& wi) const = 0;
  /// solid-angle pdf with which sample() returns wi (non-delta part; 0 for pure delta materials)
  virtual double pdf(const Vec3& wo, const Vec3& wi) const = 0;
  /// false when no sample (e.g. below the horizon); u2 for the direction, u_lobe to pick a lobe
  virtual bool sample(const Vec3& wo, Vec2 u2, double u_lobe, BsdfSample& out) const = 0;
  virtual bool has_delta() const { return false; }  // perfect mirror
  virtual bool is_pure_delta() const { return false; }
  /// GGX alpha of the material's widest non-delta lobe, 1 for a Lambertian part (as wide as lobes get), 0 when it
  /// has none: how much of the sky one of its shading points sees.
  virtual double widest_lobe_alpha() const = 0;
  /// GGX alpha of the material's narrowest non-delta lobe (1 for Lambertian, 0 for a pure delta material): a plastic's
  /// coat. The same as widest_lobe_alpha() for single-lobe materials.
  virtual double narrowest_lobe_alpha() const { return widest_lobe_alpha(); }
  /// The probability that sample() draws the narrowest lobe for wo (a plastic's coat: see its model above), in
  /// [0, 1]; 1 for single-lobe materials. Light techniques that follow the BSDF's lobes share samples by it.
  virtual double narrowest_lobe_probability(const Vec3& wo) const {
    (void)wo;
    return 1.0;
  }
  /// This material with a roughness floor (path regularization, integrator.h): every GGX lobe at least `alpha`
  /// wide, a delta lobe replaced by a GGX lobe of alpha `alpha` with the same reflectance; nullptr when no lobe is
  /// narrower than `alpha` (the material itself serves). Lambertian lobes have none; a measured BRDF keeps its data
  /// (it has no roughness to raise: nullptr).
  virtual std::unique_ptr<Material> with_roughness_floor(double alpha) const {
    (void)alpha;
    return nullptr;
  }
};

std::unique_ptr<Material> make_diffuse(const Vec3& albedo);
/// The Smith masking-shadowing term of a GGX conductor: HeightCorrelated G2 = 1 / (1 + Lambda(wo) + Lambda(wi))
/// (Heitz 2014; pbrt-v4, Mitsuba 3, Blender 4 and later), or Separable G1(wo) G1(wi) (Cycles in Blender 3.x and
/// earlier, OSL's microfacet closures), which is never brighter: up to a few percent darker on rough lobes at
/// grazing angles. The sampling (visible normals) is the same for both.
enum class Shadowing { HeightCorrelated, Separable };
/// "height-correlated", "separable" (the names of the scene format's "shadowing").
const char* shadowing_name(Shadowing s);

/// GGX alpha = roughness.
std::unique_ptr<Material> make_conductor(const Vec3& eta, const Vec3& k, double roughness,
                                         Shadowing shadowing = Shadowing::HeightCorrelated);
std::unique_ptr<Material> make_plastic(const Vec3& diffuse, double roughness, double ior = 1.5);
std::unique_ptr<Material> make_mirror(const Vec3& reflectance);
/// A measured isotropic BRDF read from the MERL binary file `merl_file` (see the model above), f multiplied by `scale`
/// per RGB channel (negative or non-finite entries count as 0). Throws Error("<file>: <problem>") for a file that
/// is missing, not regular, not 90 x 90 x 180, of the wrong size (truncated or with trailing bytes), holding a NaN or
/// infinite value, or without a positive value.
std::unique_ptr<Material> make_measured(const std::string& merl_file, const Vec3& scale = Vec3(1.0));

}  // namespace envkit::render
