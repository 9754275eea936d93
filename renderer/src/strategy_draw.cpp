// A strategy's techniques at one shading point as one distribution of directions (Integrator::strategy_at()):
// what envproduct pictures and what tests compare a strategy's samples with.
#include <envkit/render/integrator.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <variant>

namespace envkit::render {

namespace {

bool draws_bsdf(Strategy s) {
  return s == Strategy::Bsdf || s == Strategy::Mis || s == Strategy::MisCompensated || s == Strategy::ProductMis ||
         s == Strategy::Auto || s == Strategy::ProductWaveletMis || s == Strategy::ProductSteerableMis ||
         s == Strategy::ProductShMis;
}

bool draws_table(Strategy s) {
  return s == Strategy::Light || s == Strategy::Mis || s == Strategy::MisCompensated || s == Strategy::Product ||
         s == Strategy::ProductMis || s == Strategy::Auto;
}

/// u in [0, 1) kept below 1 after a rescale.
double below_one(double u) { return std::min(u, 1.0 - 0x1p-53); }

}  // namespace

/// The techniques of draw_direction(), each with its samples per shading point.
struct Integrator::DrawMix {
  int bsdf = 0;  ///< N; 0 when the strategy draws no BSDF samples
  LightTechniques light;
  std::variant<std::monostate, ProductWavelet::Point, BasisProductPoint> point;
  int point_count = 0;  ///< M of a seed sampler's product

  double total() const {
    double sum = bsdf + point_count;
    for (int k = 0; k < light.count; ++k) sum += light.parts[std::size_t(k)].count;
    return sum;
  }
};

Integrator::DrawMix Integrator::draw_mix(const ShadingPoint& x) const {
  DrawMix mix;
  const SampleCounts n = counts(x.material);
  const Strategy s = options_.strategy;
  if (x.material.is_pure_delta() || draws_bsdf(s)) mix.bsdf = x.material.is_pure_delta() ? 1 : n.bsdf;
  if (x.material.is_pure_delta()) return mix;
  if (draws_table(s)) mix.light = techniques(x, n.light, choice_for(x.material));
  if (wavelet_) mix.point = wavelet_point(x);
  if (steerable_) mix.point = steerable_->at(table_normal(x), table_wo(x), x.material);
  if (sh_) mix.point = sh_->at(table_normal(x), table_wo(x), x.material);
  if (!std::holds_alternative<std::monostate>(mix.point)) mix.point_count = n.light;
  return mix;
}

Integrator::StrategyDistribution::StrategyDistribution(const Integrator& integrator, const Frame& frame, const Vec3& wo,
                                                       const Material& material)
    : integrator_(&integrator), frame_(frame), wo_(wo), material_(&material) {
  const ShadingPoint x{Vec3(0, 0, 0), frame_, frame_.n, wo_, material};
  mix_ = std::make_unique<DrawMix>(integrator.draw_mix(x));
}

Integrator::StrategyDistribution::StrategyDistribution(StrategyDistribution&&) noexcept = default;
Integrator::StrategyDistribution::~StrategyDistribution() = default;

Integrator::StrategyDistribution Integrator::strategy_at(const Frame& frame, const Vec3& wo,
                                                         const Material& material) const {
  return StrategyDistribution(*this, frame, wo, material);
}

Integrator::StrategyDraw Integrator::StrategyDistribution::sample(Vec2 u, double u_technique) const {
  const DrawMix& mix = *mix_;
  const double total = mix.total();
  if (!(total > 0.0)) return {};
  double t = below_one(std::clamp(u_technique, 0.0, 1.0)) * total;
  StrategyDraw d;
  if (t < mix.bsdf) {
    BsdfSample bs;
    if (!material_->sample(wo_, u, below_one(t / mix.bsdf), bs) || !(bs.pdf > 0.0)) return {};
    d.direction = frame_.to_world(bs.wi);
    d.is_delta = bs.is_delta;
    d.pdf = bs.is_delta ? 0.0 : pdf(d.direction);
    return d;
  }
  t -= mix.bsdf;
  for (int k = 0; k < mix.light.count; ++k) {
    const LightTechnique& part = mix.light.parts[std::size_t(k)];
    if (t < part.count) {
      const LightSample ls = integrator_->light_.sample(part.table, u);
      if (!(ls.pdf > 0.0)) return {};
      d.direction = ls.direction;
      d.pdf = pdf(d.direction);
      return d;
    }
    t -= part.count;
  }
  const auto draw_point = [&](const auto& p) {
    const DirectionSample s = p.sample(u);
    if (!(s.pdf > 0.0)) return;
    d.direction = apply(integrator_->light_.rotation(), s.direction);
    d.pdf = pdf(d.direction);
  };
  if (const auto* p = std::get_if<ProductWavelet::Point>(&mix.point)) draw_point(*p);
  if (const auto* p = std::get_if<BasisProductPoint>(&mix.point)) draw_point(*p);
  return d;
}

double Integrator::StrategyDistribution::pdf(const Vec3& wi) const {
  const DrawMix& mix = *mix_;
  const double total = mix.total();
  if (!(total > 0.0)) return 0.0;
  double sum = mix.bsdf > 0 ? mix.bsdf * material_->pdf(wo_, frame_.to_local(wi)) : 0.0;
  for (int k = 0; k < mix.light.count; ++k) {
    const LightTechnique& part = mix.light.parts[std::size_t(k)];
    if (part.count > 0) sum += part.count * integrator_->light_.pdf(part.table, wi);
  }
  const Vec3 table_wi = integrator_->light_.to_table(wi);
  if (const auto* p = std::get_if<ProductWavelet::Point>(&mix.point)) sum += mix.point_count * p->pdf(table_wi);
  if (const auto* p = std::get_if<BasisProductPoint>(&mix.point)) sum += mix.point_count * p->pdf(table_wi);
  const double density = sum / total;
  return std::isfinite(density) ? density : 0.0;
}

}  // namespace envkit::render
