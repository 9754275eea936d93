/// Perfect mirror: one delta lobe, constant reflectance (see material.h).
#include <envkit/render/material.h>

#include "material_microfacet.h"

namespace envkit::render {

namespace {

/// A mirror under a roughness floor: GGX of alpha `alpha`, height-correlated masking-shadowing, the mirror's
/// reflectance in place of a Fresnel term, visible-normal sampling (see material.h).
class RoughMirrorMaterial final : public Material {
 public:
  RoughMirrorMaterial(const Vec3& reflectance, double alpha)
      : reflectance_(reflectance), alpha_(detail::clamp_alpha(alpha)) {}

  const char* name() const override { return "mirror"; }
  double widest_lobe_alpha() const override { return alpha_; }

  Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
    Vec3 h;
    if (!detail::above(wo) || !detail::above(wi) || !detail::half_vector(wo, wi, h)) return Vec3(0.0);
    return reflectance_ * (detail::ggx_d(alpha_, h) * detail::smith_g2_cos_over_4cos(alpha_, wo.z, wi.z));
  }

  double pdf(const Vec3& wo, const Vec3& wi) const override { return detail::ggx_reflection_pdf(alpha_, wo, wi); }

  bool sample(const Vec3& wo, Vec2 u2, double /*u_lobe*/, BsdfSample& out) const override {
    return detail::ggx_reflection_sample(*this, alpha_, wo, u2, out);
  }

 private:
  Vec3 reflectance_;
  double alpha_;
};

class MirrorMaterial final : public Material {
 public:
  explicit MirrorMaterial(const Vec3& reflectance) {
    const auto c = [](double x) { return std::isfinite(x) ? std::max(0.0, x) : 0.0; };
    reflectance_ = Vec3(c(reflectance.x), c(reflectance.y), c(reflectance.z));
  }

  const char* name() const override { return "mirror"; }
  double widest_lobe_alpha() const override { return 0.0; }
  Vec3 eval(const Vec3& /*wo*/, const Vec3& /*wi*/) const override { return Vec3(0.0); }
  double pdf(const Vec3& /*wo*/, const Vec3& /*wi*/) const override { return 0.0; }

  /// wi = the mirror direction of wo; f_cos = reflectance (the Dirac's weight: f cos / pdf = reflectance);
  /// pdf = 1 (the probability of the only lobe).
  bool sample(const Vec3& wo, Vec2 /*u2*/, double /*u_lobe*/, BsdfSample& out) const override {
    if (!detail::above(wo)) return false;
    out.wi = Vec3(-wo.x, -wo.y, wo.z);
    out.f_cos = reflectance_;
    out.pdf = 1.0;
    out.is_delta = true;
    return true;
  }

  bool has_delta() const override { return true; }
  bool is_pure_delta() const override { return true; }
  std::unique_ptr<Material> with_roughness_floor(double alpha) const override {
    if (!(alpha > 0.0)) return nullptr;
    return std::make_unique<RoughMirrorMaterial>(reflectance_, alpha);
  }

 private:
  Vec3 reflectance_;
};

}  // namespace

std::unique_ptr<Material> make_mirror(const Vec3& reflectance) { return std::make_unique<MirrorMaterial>(reflectance); }

}  // namespace envkit::render
