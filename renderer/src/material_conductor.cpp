/// Rough conductor: GGX, Smith height-correlated (or separable) masking-shadowing, complex conductor Fresnel,
/// visible-normal sampling (see material.h).
#include <envkit/render/material.h>

#include "material_microfacet.h"

namespace envkit::render {

namespace {

class ConductorMaterial final : public Material {
 public:
  ConductorMaterial(const Vec3& eta, const Vec3& k, double roughness, Shadowing shadowing)
      : eta_(clean(eta)), k_(clean(k)), alpha_(detail::clamp_alpha(roughness)), shadowing_(shadowing) {}

  const char* name() const override { return "conductor"; }
  double widest_lobe_alpha() const override { return alpha_; }
  std::unique_ptr<Material> with_roughness_floor(double alpha) const override {
    if (!(detail::clamp_alpha(alpha) > alpha_)) return nullptr;
    return std::make_unique<ConductorMaterial>(eta_, k_, alpha, shadowing_);
  }

  Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
    Vec3 h;
    if (!detail::above(wo) || !detail::above(wi) || !detail::half_vector(wo, wi, h)) return Vec3(0.0);
    const double g = shadowing_ == Shadowing::Separable ? detail::smith_g1g1_cos_over_4cos(alpha_, wo.z, wi.z)
                                                        : detail::smith_g2_cos_over_4cos(alpha_, wo.z, wi.z);
    const double scalar = detail::ggx_d(alpha_, h) * g;
    return fresnel(wo ^ h) * scalar;
  }

  double pdf(const Vec3& wo, const Vec3& wi) const override { return detail::ggx_reflection_pdf(alpha_, wo, wi); }

  bool sample(const Vec3& wo, Vec2 u2, double /*u_lobe*/, BsdfSample& out) const override {
    return detail::ggx_reflection_sample(*this, alpha_, wo, u2, out);
  }

 private:
  static Vec3 clean(const Vec3& v) {
    const auto c = [](double x) { return std::isfinite(x) ? std::max(0.0, x) : 0.0; };
    return Vec3(c(v.x), c(v.y), c(v.z));
  }
  Vec3 fresnel(double cos_i) const {
    return Vec3(detail::fresnel_conductor(cos_i, eta_.x, k_.x), detail::fresnel_conductor(cos_i, eta_.y, k_.y),
                detail::fresnel_conductor(cos_i, eta_.z, k_.z));
  }

  Vec3 eta_, k_;
  double alpha_;
  Shadowing shadowing_;
};

}  // namespace

std::unique_ptr<Material> make_conductor(const Vec3& eta, const Vec3& k, double roughness, Shadowing shadowing) {
  return std::make_unique<ConductorMaterial>(eta, k, roughness, shadowing);
}

const char* shadowing_name(Shadowing s) { return s == Shadowing::Separable ? "separable" : "height-correlated"; }

}  // namespace envkit::render
