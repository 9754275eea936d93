/// Rough plastic: GGX dielectric coat over a Lambertian base, Fresnel-weighted layering (Mitsuba's roughplastic,
/// nonlinear variant); one lobe sampled per call, chosen in proportion to the estimated albedos (see material.h).
#include <envkit/render/material.h>

#include "material_microfacet.h"

namespace envkit::render {

namespace {

/// Hemispherical-average Fresnel reflectance of a smooth dielectric seen from outside:
/// Fdr_ext = 2 int_0^1 F(mu) mu dmu, by composite Simpson's rule on 2048 intervals (accurate to ~1e-9).
double diffuse_fresnel_external(double ior) {
  constexpr int n = 2048;
  double sum = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double mu = double(i) / n;
    const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    sum += w * detail::fresnel_dielectric(mu, ior) * mu;
  }
  return 2.0 * sum / (3.0 * n);
}

class PlasticMaterial final : public Material {
 public:
  PlasticMaterial(const Vec3& diffuse, double roughness, double ior)
      : diffuse_(clean(diffuse)),
        alpha_(detail::clamp_alpha(roughness)),
        ior_(std::isfinite(ior) && ior >= 1.0 ? ior : 1.5) {
    const double fdr_int = 1.0 - (1.0 - diffuse_fresnel_external(ior_)) / (ior_ * ior_);
    const auto scale = [&](double kd) { return kd / (kPi * ior_ * ior_ * (1.0 - kd * fdr_int)); };
    diffuse_scale_ = Vec3(scale(diffuse_.x), scale(diffuse_.y), scale(diffuse_.z));
    mean_diffuse_ = (diffuse_.x + diffuse_.y + diffuse_.z) / 3.0;
  }

  const char* name() const override { return "plastic"; }
  double widest_lobe_alpha() const override { return 1.0; }
  double narrowest_lobe_alpha() const override { return alpha_; }
  std::unique_ptr<Material> with_roughness_floor(double alpha) const override {
    if (!(detail::clamp_alpha(alpha) > alpha_)) return nullptr;
    return std::make_unique<PlasticMaterial>(diffuse_, alpha, ior_);
  }
  double narrowest_lobe_probability(const Vec3& wo) const override {
    return detail::above(wo) ? specular_probability(wo.z) : 0.0;
  }

  Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
    Vec3 h;
    if (!detail::above(wo) || !detail::above(wi) || !detail::half_vector(wo, wi, h)) return Vec3(0.0);
    const double spec = detail::fresnel_dielectric(wo ^ h, ior_) * detail::ggx_d(alpha_, h) *
                        detail::smith_g2_cos_over_4cos(alpha_, wo.z, wi.z);
    const double transmit =
        (1.0 - detail::fresnel_dielectric(wo.z, ior_)) * (1.0 - detail::fresnel_dielectric(wi.z, ior_)) * wi.z;
    return diffuse_scale_ * transmit + Vec3(spec);
  }

  double pdf(const Vec3& wo, const Vec3& wi) const override {
    Vec3 h;
    if (!detail::above(wo) || !detail::above(wi) || !detail::half_vector(wo, wi, h)) return 0.0;
    const double p_spec = specular_probability(wo.z);
    return p_spec * detail::vndf_reflection_pdf(alpha_, wo.z, h) + (1.0 - p_spec) * wi.z / kPi;
  }

  bool sample(const Vec3& wo, Vec2 u2, double u_lobe, BsdfSample& out) const override {
    if (!detail::above(wo)) return false;
    const double p_spec = specular_probability(wo.z);
    Vec3 wi;
    if (u_lobe < p_spec) {
      wi = detail::reflect(wo, detail::sample_vndf(alpha_, wo, u2)).normalized();
    } else {
      wi = detail::sample_cosine_hemisphere(u2);
    }
    if (!(wi.z > 0.0)) return false;
    out.wi = wi;
    out.f_cos = eval(wo, wi);
    out.pdf = pdf(wo, wi);
    out.is_delta = false;
    return out.pdf > 0.0;
  }

  /// Probability of sampling the specular lobe: F(cos_o) / (F(cos_o) + (1 - F(cos_o)) mean(diffuse)), i.e. in
  /// proportion to the estimated albedos of the coat and of the base. 1 for a black base.
  double specular_probability(double cos_o) const {
    const double f = detail::fresnel_dielectric(cos_o, ior_);
    const double d = (1.0 - f) * mean_diffuse_;
    return f + d > 0.0 ? f / (f + d) : 1.0;
  }

 private:
  static Vec3 clean(const Vec3& v) {
    const auto c = [](double x) { return std::isfinite(x) ? std::clamp(x, 0.0, 1.0) : 0.0; };
    return Vec3(c(v.x), c(v.y), c(v.z));
  }

  Vec3 diffuse_;
  double alpha_;
  double ior_;
  Vec3 diffuse_scale_;  // diffuse / (pi ior^2 (1 - diffuse Fdr_int)) per channel
  double mean_diffuse_ = 0.0;
};

}  // namespace

std::unique_ptr<Material> make_plastic(const Vec3& diffuse, double roughness, double ior) {
  return std::make_unique<PlasticMaterial>(diffuse, roughness, ior);
}

}  // namespace envkit::render
