#include <envkit/core/error.h>
#include <envkit/render/frame.h>
#include <envkit/render/integrator.h>
#include <envkit/tables/sun_split.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace envkit::render {

namespace {

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool is_black(const Vec3& v) { return v.x == 0.0 && v.y == 0.0 && v.z == 0.0; }
Vec3 mul(const Vec3& a, const Vec3& b) { return Vec3(a.x * b.x, a.y * b.y, a.z * b.z); }

}  // namespace

SampleCounts sample_counts(const IntegratorOptions& options, const Material& material) {
  const bool narrow = material.narrowest_lobe_alpha() < kWideLobeAlpha;
  const SampleCounts by_lobe = options.max_depth > 1 ? SampleCounts{kPathBsdfSamples, kPathLightSamples}
                               : narrow              ? SampleCounts{kNarrowBsdfSamples, kNarrowLightSamples}
                                                     : SampleCounts{1, kWideLightSamples};
  return {options.bsdf_samples.value_or(by_lobe.bsdf), options.light_samples.value_or(by_lobe.light)};
}

bool takes_sun_samples(const Material& material) { return material.widest_lobe_alpha() >= kSunSampleAlpha; }

const char* strategy_name(Strategy s) {
  switch (s) {
    case Strategy::Bsdf:
      return "bsdf";
    case Strategy::Light:
      return "light";
    case Strategy::Mis:
      return "mis";
    case Strategy::MisCompensated:
      return "mis-compensated";
    case Strategy::Product:
      return "product";
    case Strategy::ProductMis:
      return "product-mis";
    case Strategy::ProductWavelet:
      return "product-wavelet";
    case Strategy::ProductWaveletMis:
      return "product-wavelet-mis";
    case Strategy::Auto:
      return "auto";
    case Strategy::ProductSteerable:
      return "product-steerable";
    case Strategy::ProductSteerableMis:
      return "product-steerable-mis";
    case Strategy::ProductSh:
      return "product-sh";
    case Strategy::ProductShMis:
      return "product-sh-mis";
  }
  return "?";
}

std::string strategy_names(const std::string& separator) {
  std::string names;
  for (Strategy s : kStrategies) names += (names.empty() ? "" : separator) + strategy_name(s);
  return names;
}

Strategy parse_strategy(const std::string& name) {
  for (Strategy s : kStrategies)
    if (name == strategy_name(s)) return s;
  throw Error("unknown strategy '" + name + "' (valid: " + strategy_names(", ") + ")");
}

const char* heuristic_name(Heuristic h) { return h == Heuristic::Balance ? "balance" : "power"; }

Heuristic parse_heuristic(const std::string& name) {
  if (name == "balance") return Heuristic::Balance;
  if (name == "power") return Heuristic::Power;
  throw Error("unknown heuristic '" + name + "' (valid: balance, power)");
}

const char* integrator_field_name(IntegratorField field) {
  switch (field) {
    case IntegratorField::Strategy:
      return "strategy";
    case IntegratorField::LightMethod:
      return "light_method";
    case IntegratorField::BsdfSamples:
      return "bsdf_samples";
    case IntegratorField::LightSamples:
      return "light_samples";
    case IntegratorField::SunSamples:
      return "sun_samples";
    case IntegratorField::MaxDepth:
      return "max_depth";
    case IntegratorField::Regularization:
      return "regularization";
    case IntegratorField::WaveletResolution:
      return "wavelet.resolution";
    case IntegratorField::WaveletNormalBins:
      return "wavelet.normal_bins";
    case IntegratorField::WaveletWoBins:
      return "wavelet.wo_bins";
    case IntegratorField::WaveletKeptCoefficients:
      return "wavelet.kept_coefficients";
    case IntegratorField::SteerableOrder:
      return "steerable.order";
    case IntegratorField::SteerableResolution:
      return "steerable.resolution";
    case IntegratorField::SteerableWoBins:
      return "steerable.wo_bins";
    case IntegratorField::SteerableDefensive:
      return "steerable.defensive";
    case IntegratorField::ShOrder:
      return "sh.order";
    case IntegratorField::ShResolution:
      return "sh.resolution";
    case IntegratorField::ShWoBins:
      return "sh.wo_bins";
    case IntegratorField::ShDefensive:
      return "sh.defensive";
  }
  return "?";
}

IntegratorOptionsError::IntegratorOptionsError(IntegratorField at, std::function<std::string(const Speller&)> compose)
    : Error(compose([](IntegratorField f) { return std::string(integrator_field_name(f)); })),
      field(at),
      compose_(std::move(compose)) {}

namespace {

using Speller = IntegratorOptionsError::Speller;

[[noreturn]] void refuse(IntegratorField field, std::function<std::string(const Speller&)> compose) {
  throw IntegratorOptionsError(field, std::move(compose));
}

/// Refuses the seed samplers' options out of range, the field named with its value and rule.
void validate_seed_options(const IntegratorOptions& o) {
  using F = IntegratorField;
  const auto refuse_range = [](F field, const std::string& value, const std::string& rule) {
    refuse(field, [=](const Speller& n) { return n(field) + " " + value + ": " + rule; });
  };
  if (const auto bad = out_of_range(o.wavelet)) {
    static constexpr F kFields[] = {F::WaveletResolution, F::WaveletNormalBins, F::WaveletWoBins,
                                    F::WaveletKeptCoefficients};
    refuse_range(kFields[int(bad->member)], bad->value, bad->rule);
  }
  const auto basis = [&](const BasisProductOptions& options, const std::array<F, 4>& fields) {
    if (const auto bad = out_of_range(options)) refuse_range(fields[std::size_t(bad->member)], bad->value, bad->rule);
  };
  basis(o.steerable, {F::SteerableOrder, F::SteerableResolution, F::SteerableWoBins, F::SteerableDefensive});
  basis(o.sh, {F::ShOrder, F::ShResolution, F::ShWoBins, F::ShDefensive});
}

}  // namespace

void validate(const IntegratorOptions& o) {
  using F = IntegratorField;
  // Counts the options leave unset are at least 1 (sample_counts()): only given counts can fail these rules.
  const int n_min = o.bsdf_samples.value_or(1), m_min = o.light_samples.value_or(1);
  if (n_min < 0 || m_min < 0)
    refuse(n_min < 0 ? F::BsdfSamples : F::LightSamples, [](const Speller&) { return "sample counts must be >= 0"; });
  if (o.max_depth < 1) refuse(F::MaxDepth, [](const Speller& n) { return n(F::MaxDepth) + " must be >= 1"; });
  const Strategy s = o.strategy;
  if (s == Strategy::Bsdf && n_min < 1)
    refuse(F::BsdfSamples, [](const Speller& n) { return "strategy bsdf needs " + n(F::BsdfSamples) + " >= 1"; });
  if (s == Strategy::Light && m_min < 1)
    refuse(F::LightSamples, [](const Speller& n) { return "strategy light needs " + n(F::LightSamples) + " >= 1"; });
  if ((s == Strategy::Mis || s == Strategy::MisCompensated) && n_min + m_min < 1)
    refuse(F::Strategy, [](const Speller&) { return "strategy mis needs at least one sample"; });
  if (s == Strategy::MisCompensated && n_min < 1)
    refuse(F::BsdfSamples, [](const Speller& n) {
      return "strategy mis-compensated needs " + n(F::BsdfSamples) +
             " >= 1 (BSDF sampling covers what the compensated table leaves out)";
    });
  if (o.sun_samples < 0) refuse(F::SunSamples, [](const Speller& n) { return n(F::SunSamples) + " must be >= 0"; });
  if (!(std::isfinite(o.regularization) && o.regularization >= 0.0))
    refuse(F::Regularization,
           [](const Speller& n) { return n(F::Regularization) + " must be a finite number >= 0 (0 = unbiased)"; });
  validate_seed_options(o);
  const bool product = s == Strategy::Product || s == Strategy::ProductMis || s == Strategy::Auto;
  const bool wavelet = s == Strategy::ProductWavelet || s == Strategy::ProductWaveletMis;
  if (s == Strategy::ProductWavelet && m_min < 1)
    refuse(F::LightSamples,
           [](const Speller& n) { return "strategy product-wavelet needs " + n(F::LightSamples) + " >= 1"; });
  if (s == Strategy::ProductWaveletMis && n_min + m_min < 1)
    refuse(F::Strategy, [](const Speller&) { return "strategy product-wavelet-mis needs at least one sample"; });
  if (wavelet && o.light_method != SamplingMethod::Hierarchical)
    refuse(F::LightMethod, [method = o.light_method](const Speller& n) {
      return n(F::LightMethod) + " " + method_name(method) +
             ": the product-wavelet strategies read the hierarchical table";
    });
  const bool basis = s == Strategy::ProductSteerable || s == Strategy::ProductSteerableMis ||
                     s == Strategy::ProductSh || s == Strategy::ProductShMis;
  const bool basis_mis = s == Strategy::ProductSteerableMis || s == Strategy::ProductShMis;
  if (basis && !basis_mis && m_min < 1)
    refuse(F::LightSamples, [s](const Speller& n) {
      return std::string("strategy ") + strategy_name(s) + " needs " + n(F::LightSamples) + " >= 1";
    });
  if (basis_mis && n_min + m_min < 1)
    refuse(F::Strategy,
           [s](const Speller&) { return std::string("strategy ") + strategy_name(s) + " needs at least one sample"; });
  if (basis && o.light_method != SamplingMethod::Hierarchical)
    refuse(F::LightMethod, [s, method = o.light_method](const Speller& n) {
      return n(F::LightMethod) + " " + method_name(method) + ": the " + strategy_name(s) +
             " strategy reads the hierarchical table";
    });
  if (s == Strategy::Product && m_min < 1)
    refuse(F::LightSamples, [](const Speller& n) { return "strategy product needs " + n(F::LightSamples) + " >= 1"; });
  if ((s == Strategy::ProductMis || s == Strategy::Auto) && n_min + m_min < 1)
    refuse(F::Strategy,
           [s](const Speller&) { return std::string("strategy ") + strategy_name(s) + " needs at least one sample"; });
  if (product && o.light_method != SamplingMethod::Hierarchical)
    refuse(F::LightMethod, [method = o.light_method](const Speller& n) {
      return n(F::LightMethod) + " " + method_name(method) +
             ": the product strategies refine the hierarchical table (another method needs " + n(F::Strategy) +
             " light, mis or mis-compensated)";
    });
}

Integrator::Integrator(const Scene& scene, const EnvironmentLight& light, const IntegratorOptions& options,
                       const Camera* camera)
    : scene_(scene), light_(light), options_(options) {
  validate(options_);
  const Strategy s = options_.strategy;
  if (s != Strategy::Bsdf) {
    const bool compensated = s == Strategy::MisCompensated;
    // The light counts are the shading point's (techniques()).
    whole_ = {{LightTechnique{light_.distribution(options_.light_method, compensated), 0}}, 1};
    const bool whole_map = s == Strategy::ProductWavelet || s == Strategy::ProductWaveletMis ||
                           s == Strategy::ProductSteerable || s == Strategy::ProductSteerableMis ||
                           s == Strategy::ProductSh || s == Strategy::ProductShMis;
    if (options_.sun_samples > 0 && !whole_map) {
      // A table file may hold the split (envbake --tables ...,sun); else it is built here.
      if (auto stored = light_.tables().stored_sun_split(options_.light_method, compensated))
        sun_ = std::move(*stored);
      else if (std::optional<SunSplit> made = SunSplit::make(light_.tables(), options_.light_method, compensated))
        sun_ = std::make_shared<const SunSplit>(std::move(*made));
      if (sun_) {
        split_ = {{LightTechnique{sun_->residual(), 0}, LightTechnique{sun_->sun_distribution(), options_.sun_samples}},
                  2};
        sun_axis_ = apply(light_.rotation(), sun_->sun().direction);
      }
    }
  }
  direct_ = s == Strategy::Bsdf                              ? &Integrator::direct_bsdf
            : s == Strategy::Light || s == Strategy::Product ? &Integrator::direct_light
            : s == Strategy::ProductWavelet                  ? &Integrator::direct_product_wavelet
            : s == Strategy::ProductWaveletMis               ? &Integrator::direct_product_wavelet_mis
            : s == Strategy::ProductSteerable                ? &Integrator::direct_product_steerable
            : s == Strategy::ProductSteerableMis             ? &Integrator::direct_product_steerable_mis
            : s == Strategy::ProductSh                       ? &Integrator::direct_product_sh
            : s == Strategy::ProductShMis                    ? &Integrator::direct_product_sh_mis
                                                             : &Integrator::direct_mis;
  build_regularized_materials();
  const bool product = s == Strategy::Product || s == Strategy::ProductMis || s == Strategy::Auto;
  for (int m = 0; m < scene_.material_count(); ++m)
    choices_.push_back({product, sun_ && takes_sun_samples(scene_.material(m))});
  if (product) build_product_tables(s == Strategy::Auto && camera);
  if (s == Strategy::Auto && camera) choose_by_pilot(*camera);
  if (s == Strategy::ProductWavelet || s == Strategy::ProductWaveletMis) build_product_wavelet();
  if (s == Strategy::ProductSteerable || s == Strategy::ProductSteerableMis)
    steerable_ = std::make_unique<ProductSteerable>(light_.distribution(SamplingMethod::Hierarchical, false),
                                                    shaded_materials(), options_.steerable);
  if (s == Strategy::ProductSh || s == Strategy::ProductShMis)
    sh_ = std::make_unique<ProductSh>(light_.distribution(SamplingMethod::Hierarchical, false), shaded_materials(),
                                      options_.sh);
}

void Integrator::build_product_wavelet() {
  wavelet_ = std::make_unique<ProductWavelet>(light_.distribution(SamplingMethod::Hierarchical, false),
                                              shaded_materials(), options_.wavelet);
}

std::array<std::optional<Lobe>, 2> Integrator::product_lobes(const Material& material) {
  const auto lobe = [](double alpha) -> std::optional<Lobe> {
    if (!(alpha > 0.0)) return std::nullopt;
    return alpha >= 1.0 ? Lobe{Lobe::Shape::Cosine, 1.0} : Lobe{Lobe::Shape::Ggx, std::max(alpha, 1e-3)};
  };
  if (material.is_pure_delta()) return {};
  const std::optional<Lobe> widest = lobe(material.widest_lobe_alpha());
  const std::optional<Lobe> narrowest = lobe(material.narrowest_lobe_alpha());
  if (!widest || narrowest == widest) return {widest, std::nullopt};
  return {widest, narrowest};
}

Vec3 Integrator::lobe_axis(const Lobe& lobe, const ShadingPoint& x) {
  return lobe.shape == Lobe::Shape::Cosine ? x.frame.n : x.frame.to_world(Vec3(-x.wo.x, -x.wo.y, x.wo.z));
}

void Integrator::build_product_tables(bool every_lobe) {
  // The scene's lobes; with a sun, those of materials that take it apart get tables over the rest of the map, the
  // others over the whole map (techniques()).
  std::vector<Lobe> whole, split;
  const auto add = [](std::vector<Lobe>& set, const Material& material) {
    for (const std::optional<Lobe>& lobe : product_lobes(material))
      if (lobe && std::find(set.begin(), set.end(), *lobe) == set.end()) set.push_back(*lobe);
  };
  for (const Material* shaded : shaded_materials()) {
    const LightChoice choice = choice_for(*shaded);
    if (every_lobe || !choice.sun_apart) add(whole, *shaded);
    if (sun_ && (every_lobe || choice.sun_apart)) add(split, *shaded);
  }
  if (!whole.empty()) product_whole_ = std::make_unique<LobeProductTables>(*whole_.parts[0].table.first, whole);
  if (!split.empty()) product_split_ = std::make_unique<LobeProductTables>(*split_.parts[0].table.first, split);
}

Integrator::~Integrator() = default;

double roulette_survival(double throughput, int depth, int max_depth) {
  // Vertices shaded before the decision (0 .. depth) against those a survivor can still shade.
  const double shaded = double(depth) + 1.0, remaining = double(std::max(max_depth - depth - 1, 1));
  const double q = throughput * std::sqrt(shaded / remaining);
  return std::isfinite(q) ? std::clamp(q, kRouletteMinSurvival, 1.0) : 1.0;
}

double regularization_floor(double regularization, double min_pdf) {
  if (!(regularization > 0.0) || !(min_pdf < regularization)) return 0.0;
  const double blur = 0.5 * std::sqrt(1.0 - std::max(min_pdf, 0.0) / regularization);
  return std::min(std::floor(blur / kRegularizationStep) * kRegularizationStep, kRegularizationMaxFloor);
}

void Integrator::build_regularized_materials() {
  // No vertex but the camera hit (never widened) without a continuation: nothing to build.
  if (!(options_.regularization > 0.0) || options_.max_depth < 2) return;
  const int levels = int(std::lround(kRegularizationMaxFloor / kRegularizationStep));
  regularized_.resize(std::size_t(scene_.material_count()));
  for (int m = 0; m < scene_.material_count(); ++m)
    for (int k = 0; k < levels; ++k)
      regularized_[std::size_t(m)].push_back(scene_.material(m).with_roughness_floor((k + 1) * kRegularizationStep));
}

const Material& Integrator::regularized(int index, double floor) const {
  const int k = int(std::lround(floor / kRegularizationStep)) - 1;
  if (k < 0 || std::size_t(index) >= regularized_.size()) return scene_.material(index);
  const std::vector<std::unique_ptr<Material>>& copies = regularized_[std::size_t(index)];
  const Material* widened = std::size_t(k) < copies.size() ? copies[std::size_t(k)].get() : nullptr;
  return widened ? *widened : scene_.material(index);
}

std::vector<const Material*> Integrator::shaded_materials() const {
  std::vector<const Material*> materials;
  for (int m = 0; m < scene_.material_count(); ++m) materials.push_back(&scene_.material(m));
  for (const std::vector<std::unique_ptr<Material>>& copies : regularized_)
    for (const std::unique_ptr<Material>& widened : copies)
      if (widened) materials.push_back(widened.get());
  return materials;
}

int Integrator::product_lobe_count() const {
  return (product_whole_ ? int(product_whole_->lobes().size()) : 0) +
         (product_split_ ? int(product_split_->lobes().size()) : 0);
}

std::size_t Integrator::product_table_bytes() const {
  return (product_whole_ ? product_whole_->bytes() : 0) + (product_split_ ? product_split_->bytes() : 0);
}

double Integrator::mis_weight(double a, double b) const {
  if (options_.heuristic == Heuristic::Power) {
    a *= a;
    b *= b;
  }
  const double sum = a + b;
  return sum > 0.0 && std::isfinite(sum) ? a / sum : (std::isinf(a) ? 1.0 : 0.0);
}

LightChoice Integrator::choice_for(const Material& material) const {
  for (int m = 0; m < scene_.material_count(); ++m)
    if (&scene_.material(m) == &material) return choices_[std::size_t(m)];
  return {has_product_tables(), sun_ && takes_sun_samples(material)};
}

Integrator::LightTechniques Integrator::techniques(const ShadingPoint& x, int light_samples, LightChoice choice) const {
  const bool split = sun_ && choice.sun_apart;
  LightTechniques t = split ? split_ : whole_;
  t.parts[0].count = light_samples;
  const LobeProductTables* tables = !choice.product ? nullptr : split ? product_split_.get() : product_whole_.get();
  if (!tables) return t;
  // By lobe, not by material: a material outside the scene (direct() is public) with a lobe of the scene's gets
  // its table too; one without keeps the plain table.
  const std::array<std::optional<Lobe>, 2> lobes = product_lobes(x.material);
  const int widest = lobes[0] ? tables->find(*lobes[0]) : -1;
  if (widest < 0) return t;
  const LobeProductTables::Table wide = tables->table(widest, light_.to_table(lobe_axis(*lobes[0], x)));
  t.parts[0].table = wide.distribution;
  const int narrowest = lobes[1] ? tables->find(*lobes[1]) : -1;
  if (narrowest < 0) return t;
  // Two lobes: each lobe's expected share of the light, its albedo (the BSDF's own choice) times the sky it sees.
  const LobeProductTables::Table narrow = tables->table(narrowest, light_.to_table(lobe_axis(*lobes[1], x)));
  const double a = x.material.narrowest_lobe_probability(x.wo);
  const double sky_n = a * narrow.mean_importance, sky_w = (1.0 - a) * wide.mean_importance;
  t.parts[0].table =
      LightTable(wide.distribution, narrow.distribution, sky_n + sky_w > 0.0 ? sky_n / (sky_n + sky_w) : a);
  return t;
}

double Integrator::sun_pdf(const Vec3& wi_world) const {
  if (!sun_ || (wi_world ^ sun_axis_) < sun_->cos_bound()) return 0.0;
  return light_.pdf(sun_->sun_distribution(), wi_world);
}

Integrator::BsdfDraw Integrator::bsdf_draw(const Sampler& sampler, std::uint32_t dimension, int k, int n) {
  return {sampler.point_2d(dimension, std::uint32_t(k), std::uint32_t(n)),
          sampler.point_1d(dimension + 1, std::uint32_t(k), std::uint32_t(n))};
}

Integrator::Continuation* Integrator::continued_by(Continuation* next, int bsdf_samples) {
  if (!next || bsdf_samples != 1) return nullptr;
  next->drawn = true;
  return next;
}

bool Integrator::escapes(const Ray& ray, const BsdfSample& sample, Continuation* next) const {
  if (!next) return !scene_.occluded(ray);
  next->weight = sample.f_cos / sample.pdf;
  next->pdf = sample.pdf;
  next->is_delta = sample.is_delta;
  next->ray = ray;
  next->hit = scene_.intersect(ray, next->next);
  return !next->hit;
}

Integrator::BsdfTerm Integrator::bsdf_term(const ShadingPoint& x, BsdfDraw draw, const LightTechniques* light,
                                           Continuation* next) const {
  BsdfTerm t;
  BsdfSample bs;
  if (!x.material.sample(x.wo, draw.u, draw.u_lobe, bs) || !(bs.pdf > 0.0) || is_black(bs.f_cos)) return t;
  t.wi_world = x.frame.to_world(bs.wi);
  if ((t.wi_world ^ x.ng) <= 0.0) return t;  // the shading normal let it through the geometric surface
  t.pdf = bs.pdf;
  t.is_delta = bs.is_delta;
  const auto look_up = [&] {
    return light ? light_.lookup(light->parts[0].table, t.wi_world) : light_.lookup(t.wi_world);
  };
  // A shadow ray looks its texel up before it is traced and reads it after: the texel arrives from memory while the
  // ray is traced. A continuation often hits a surface, and then needs no texel: it looks up only if it escapes.
  LightSample l;
  if (!next) l = look_up();
  if (!escapes(Ray{x.origin, t.wi_world}, bs, next)) return t;
  if (next) l = look_up();
  t.value = mul(bs.f_cos, light_.radiance(l)) / bs.pdf;
  // The parts' supports are disjoint (the sun's texels, the rest): at most one density is not 0.
  if (light)
    t.light_density =
        light->parts[0].count * l.pdf + (light->count > 1 ? light->parts[1].count * sun_pdf(t.wi_world) : 0.0);
  return t;
}

Integrator::LightTerm Integrator::light_term(const ShadingPoint& x, const LightSample& ls) const {
  LightTerm t;
  t.pdf = ls.pdf;
  if (!(ls.pdf > 0.0) || (ls.direction ^ x.ng) <= 0.0) return t;
  t.wi_local = x.frame.to_local(ls.direction);
  const Vec3 f_cos = x.material.eval(x.wo, t.wi_local);
  if (is_black(f_cos) || scene_.occluded(Ray{x.origin, ls.direction})) return t;
  t.value = mul(f_cos, light_.radiance(ls));  // read after the shadow ray: sample() prefetched it
  return t;
}

template <class Term>
void Integrator::for_each_light_term(const ShadingPoint& x, const LightTechnique& t, const Sampler& sampler,
                                     std::uint32_t dimension, Term&& term) const {
  constexpr int G = int(sampling::kDrawGroup);
  Vec2 u[G];
  LightSample ls[G];
  for (int g = 0; g < t.count; g += G) {
    const int n = std::min(G, t.count - g);
    for (int j = 0; j < n; ++j) u[j] = sampler.point_2d(dimension, std::uint32_t(g + j), std::uint32_t(t.count));
    light_.sample(t.table, std::span<const Vec2>(u, std::size_t(n)), std::span<LightSample>(ls, std::size_t(n)));
    for (int j = 0; j < n; ++j) term(g + j, light_term(x, ls[j]));
  }
}

Vec3 Integrator::delta_lobe_term(const ShadingPoint& x, Sampler& sampler) const {
  if (!x.material.has_delta()) return Vec3(0, 0, 0);
  const BsdfTerm b = bsdf_term(x, bsdf_draw(sampler, sampler.reserve(2), 0, 1));
  return b.is_delta ? b.value : Vec3(0, 0, 0);
}

Vec3 Integrator::direct_bsdf(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  const int N = counts(x.material).bsdf;
  const std::uint32_t dimension = sampler.reserve(2);
  Continuation* const continuation = continued_by(next, N);
  Vec3 sum(0, 0, 0);
  for (int i = 0; i < N; ++i) sum += bsdf_term(x, bsdf_draw(sampler, dimension, i, N), nullptr, continuation).value;
  return sum / double(N);
}

Vec3 Integrator::direct_light(const ShadingPoint& x, Sampler& sampler, Continuation*) const {
  const LightTechniques light = techniques(x, counts(x.material).light, choice_for(x.material));
  Vec3 sum(0, 0, 0);
  for (int k = 0; k < light.count; ++k) {
    const LightTechnique& t = light.parts[std::size_t(k)];
    for_each_light_term(x, t, sampler, sampler.reserve(1), [&](int, const LightTerm& l) {
      if (!is_black(l.value)) sum += l.value / (l.pdf * t.count);
    });
  }
  return sum + delta_lobe_term(x, sampler);  // light samples cannot reach a delta lobe
}

Vec3 Integrator::direct_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  return direct_mis_with(x, sampler, choice_for(x.material), next);
}

Vec3 Integrator::direct_mis_with(const ShadingPoint& x, Sampler& sampler, LightChoice choice,
                                 Continuation* next) const {
  const SampleCounts n = counts(x.material);
  const int N = n.bsdf;
  const LightTechniques light = techniques(x, n.light, choice);
  Vec3 sum(0, 0, 0);
  // Each light technique against the BSDF alone: the others' densities are 0 where it draws (disjoint supports).
  for (int k = 0; k < light.count; ++k) {
    const LightTechnique& t = light.parts[std::size_t(k)];
    for_each_light_term(x, t, sampler, sampler.reserve(1), [&](int, const LightTerm& l) {
      if (is_black(l.value)) return;
      const double p_b = x.material.pdf(x.wo, l.wi_local);
      sum += l.value * (mis_weight(t.count * l.pdf, N * p_b) / (t.count * l.pdf));
    });
  }
  const std::uint32_t dimension = sampler.reserve(2);
  Continuation* const continuation = continued_by(next, N);
  for (int i = 0; i < N; ++i) {
    const BsdfTerm b = bsdf_term(x, bsdf_draw(sampler, dimension, i, N), &light, continuation);
    if (!(b.pdf > 0.0) || is_black(b.value)) continue;
    if (b.is_delta) {
      sum += b.value / double(N);
      continue;
    }
    sum += b.value * (mis_weight(N * b.pdf, b.light_density) / N);
  }
  return sum;
}

Vec3 Integrator::table_normal(const ShadingPoint& x) const { return light_.to_table(x.frame.n); }
Vec3 Integrator::table_wo(const ShadingPoint& x) const { return light_.to_table(x.frame.to_world(x.wo)); }

ProductWavelet::Point Integrator::wavelet_point(const ShadingPoint& x) const {
  return wavelet_->at(table_normal(x), table_wo(x), x.material);
}

template <class Point>
Integrator::LightTerm Integrator::point_term(const ShadingPoint& x, const Point& p, Vec2 u) const {
  LightTerm t;
  const DirectionSample s = p.sample(u);
  t.pdf = s.pdf;
  const Vec3 wi_world = apply(light_.rotation(), s.direction);
  if (!(s.pdf > 0.0) || (wi_world ^ x.ng) <= 0.0) return t;
  t.wi_local = x.frame.to_local(wi_world);
  const Vec3 f_cos = x.material.eval(x.wo, t.wi_local);
  if (is_black(f_cos)) return t;
  const LightSample l = light_.lookup(wi_world);  // prefetched while the shadow ray is traced
  if (scene_.occluded(Ray{x.origin, wi_world})) return t;
  t.value = mul(f_cos, light_.radiance(l));
  return t;
}

template <class Point>
Vec3 Integrator::direct_point(const ShadingPoint& x, Sampler& sampler, const Point& p) const {
  const int M = counts(x.material).light;
  const std::uint32_t dimension = sampler.reserve(1);
  Vec3 sum(0, 0, 0);
  for (int j = 0; j < M; ++j) {
    const LightTerm l = point_term(x, p, sampler.point_2d(dimension, std::uint32_t(j), std::uint32_t(M)));
    if (!is_black(l.value)) sum += l.value / (l.pdf * M);
  }
  return sum + delta_lobe_term(x, sampler);  // product samples cannot reach a delta lobe
}

template <class Point>
Vec3 Integrator::direct_point_mis(const ShadingPoint& x, Sampler& sampler, const Point& p, Continuation* next) const {
  const SampleCounts n = counts(x.material);
  const int N = n.bsdf, M = n.light;
  Vec3 sum(0, 0, 0);
  const std::uint32_t light_dimension = sampler.reserve(1);
  for (int j = 0; j < M; ++j) {
    const LightTerm l = point_term(x, p, sampler.point_2d(light_dimension, std::uint32_t(j), std::uint32_t(M)));
    if (is_black(l.value)) continue;
    sum += l.value * (mis_weight(M * l.pdf, N * x.material.pdf(x.wo, l.wi_local)) / (M * l.pdf));
  }
  const std::uint32_t dimension = sampler.reserve(2);
  Continuation* const continuation = continued_by(next, N);
  for (int i = 0; i < N; ++i) {
    const BsdfTerm b = bsdf_term(x, bsdf_draw(sampler, dimension, i, N), nullptr, continuation);
    if (!(b.pdf > 0.0) || is_black(b.value)) continue;
    if (b.is_delta) {
      sum += b.value / double(N);
      continue;
    }
    sum += b.value * (mis_weight(N * b.pdf, M * p.pdf(light_.to_table(b.wi_world))) / N);
  }
  return sum;
}

Vec3 Integrator::direct_product_wavelet(const ShadingPoint& x, Sampler& sampler, Continuation*) const {
  return direct_point(x, sampler, wavelet_point(x));
}

Vec3 Integrator::direct_product_wavelet_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  return direct_point_mis(x, sampler, wavelet_point(x), next);
}

Vec3 Integrator::direct_product_steerable(const ShadingPoint& x, Sampler& sampler, Continuation*) const {
  return direct_point(x, sampler, steerable_->at(table_normal(x), table_wo(x), x.material));
}

Vec3 Integrator::direct_product_steerable_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  return direct_point_mis(x, sampler, steerable_->at(table_normal(x), table_wo(x), x.material), next);
}

Vec3 Integrator::direct_product_sh(const ShadingPoint& x, Sampler& sampler, Continuation*) const {
  return direct_point(x, sampler, sh_->at(table_normal(x), table_wo(x), x.material));
}

Vec3 Integrator::direct_product_sh_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  return direct_point_mis(x, sampler, sh_->at(table_normal(x), table_wo(x), x.material), next);
}

Vec3 Integrator::direct(const Vec3& position, const Frame& frame, const Vec3& ng, const Vec3& wo,
                        const Material& material, Sampler& sampler) const {
  return shade(ShadingPoint{Scene::offset_origin(position, ng), frame, ng, wo, material}, sampler, nullptr);
}

Vec3 Integrator::shade(const ShadingPoint& x, Sampler& sampler, Continuation* next) const {
  // Pure delta materials: one BSDF sample, weight 1, in every strategy (and the continuation when one is wanted).
  if (x.material.is_pure_delta())
    return bsdf_term(x, bsdf_draw(sampler, sampler.reserve(2), 0, 1), nullptr, continued_by(next, 1)).value;
  return (this->*direct_)(x, sampler, next);
}

bool Integrator::survives(const Vec3& weight, double pdf, bool is_delta, int depth, Sampler& sampler, Vec3& throughput,
                          double& min_pdf) const {
  throughput = mul(throughput, weight);
  if (is_black(throughput) || !finite(throughput)) return false;
  if (!is_delta) min_pdf = std::min(min_pdf, pdf);
  if (depth >= kRouletteStartVertex) {
    const double survival =
        roulette_survival(std::max({throughput.x, throughput.y, throughput.z}), depth, options_.max_depth);
    if (sampler.next_1d() >= survival) return false;
    throughput = throughput / survival;
  }
  return true;
}

bool Integrator::continue_apart(const ShadingPoint& x, Sampler& sampler, int depth, Vec3& throughput, double& min_pdf,
                                Ray& ray, Hit& hit) const {
  BsdfSample bs;
  if (!x.material.sample(x.wo, sampler.next_2d(), sampler.next_1d(), bs) || !(bs.pdf > 0.0)) return false;
  const Vec3 wi_world = x.frame.to_world(bs.wi);
  if ((wi_world ^ x.ng) <= 0.0) return false;
  if (!survives(bs.f_cos / bs.pdf, bs.pdf, bs.is_delta, depth, sampler, throughput, min_pdf)) return false;
  ray = Ray{x.origin, wi_world};
  return scene_.intersect(ray, hit);
}

Vec3 Integrator::radiance(const Ray& primary, Sampler& sampler) const {
  Vec3 result(0, 0, 0), throughput(1, 1, 1);
  Hit hit;
  if (!scene_.intersect(primary, hit)) {
    result = light_.radiance(primary.direction);
  } else {
    Ray ray = primary;
    // The smallest pdf of the path's non-delta continuations (regularization: the file comment).
    double min_pdf = std::numeric_limits<double>::infinity();
    for (int depth = 0; depth < options_.max_depth; ++depth) {
      const SurfaceView view = surface_view(hit.geometric_normal, hit.shading_normal, -ray.direction);
      if (!(view.wo.z > 0.0)) break;
      const Material& material = regularized(hit.material, regularization_floor(options_.regularization, min_pdf));
      const ShadingPoint x{Scene::offset_origin(hit.position, view.ng), view.frame, view.ng, view.wo, material};
      const bool last = depth + 1 >= options_.max_depth;
      Continuation next;
      result += mul(throughput, shade(x, sampler, last ? nullptr : &next));
      if (last) break;
      if (!next.drawn) {
        if (!continue_apart(x, sampler, depth, throughput, min_pdf, ray, hit)) break;
        continue;
      }
      // D's BSDF sample: an escape was its BSDF term (counted above); a hit is the next vertex.
      if (!next.hit || !survives(next.weight, next.pdf, next.is_delta, depth, sampler, throughput, min_pdf)) break;
      ray = next.ray;
      hit = next.next;
    }
  }
  if (!finite(result)) {
    nonfinite_.fetch_add(1, std::memory_order_relaxed);
    return Vec3(0, 0, 0);
  }
  return result;
}

}  // namespace envkit::render
