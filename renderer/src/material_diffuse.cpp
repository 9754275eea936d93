/// Lambertian diffuse: f = albedo / pi, cosine-weighted sampling (see material.h).
#include <envkit/render/material.h>

#include "material_microfacet.h"

namespace envkit::render {

namespace {

class DiffuseMaterial final : public Material {
 public:
  explicit DiffuseMaterial(const Vec3& albedo)
      : albedo_over_pi_(Vec3(std::max(0.0, albedo.x), std::max(0.0, albedo.y), std::max(0.0, albedo.z)) / kPi) {}

  const char* name() const override { return "diffuse"; }
  double widest_lobe_alpha() const override { return 1.0; }

  Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
    if (!detail::above(wo) || !detail::above(wi)) return Vec3(0.0);
    return albedo_over_pi_ * wi.z;
  }

  double pdf(const Vec3& wo, const Vec3& wi) const override {
    if (!detail::above(wo) || !detail::above(wi)) return 0.0;
    return wi.z / kPi;
  }

  bool sample(const Vec3& wo, Vec2 u2, double /*u_lobe*/, BsdfSample& out) const override {
    if (!detail::above(wo)) return false;
    const Vec3 wi = detail::sample_cosine_hemisphere(u2);
    if (!(wi.z > 0.0)) return false;
    out.wi = wi;
    out.f_cos = albedo_over_pi_ * wi.z;
    out.pdf = wi.z / kPi;
    out.is_delta = false;
    return true;
  }

 private:
  Vec3 albedo_over_pi_;
};

}  // namespace

std::unique_ptr<Material> make_diffuse(const Vec3& albedo) { return std::make_unique<DiffuseMaterial>(albedo); }

}  // namespace envkit::render
