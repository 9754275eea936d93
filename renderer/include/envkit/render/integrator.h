#pragma once
/// @file integrator.h
/// Direct (and optional indirect) illumination from the environment, with every sampling strategy.
///
/// Estimator structure. Surfaces emit nothing, so the radiance leaving a shading point x towards wo is
///   L(x, wo) = D(x, wo) + I(x, wo),
/// D = integral of f cos L_env V over directions that ESCAPE the scene (direct environment light, estimated by
/// the chosen strategy) and I = integral over directions that HIT a surface (estimated, when --max-depth > 1,
/// by one BSDF-sampled continuation ray that only counts when it hits a surface; an escaping continuation
/// contributes nothing to I because D holds that light). Camera rays that escape see the environment.
/// --max-depth 1 (the default) is direct illumination only.
/// Every vertex of a path, the camera hit included, estimates D by the chosen strategy with the same sample counts
/// (sample_counts()). The continuation is D's own BSDF sample where the strategy's estimator of D draws exactly one
/// (bsdf, the mis family, the product-*-mis strategies and pure delta materials, N = 1; pbrt-v4's and Cycles' path
/// tracers): that ray is traced to its first hit instead of as a shadow ray; if it escapes it is D's BSDF term
/// (with its MIS weight) and the path ends, if it hits a surface the BSDF term is 0 (occluded) and the hit is the
/// next vertex, the throughput multiplied by the same f cos / pdf. Each integral is still estimated once: D by
/// the escaping part of the sample, I by the hitting part. One ray per vertex instead of a shadow ray and a
/// continuation. Strategies without a BSDF sample (light, product, the product-* strategies without mis) or with
/// N != 1 draw the continuation apart, from the next dimensions of the sampler. The last vertex of a path
/// (and every vertex at max_depth 1) draws no continuation and is shaded exactly as direct() shades it.
/// When paths are followed (max_depth > 1) the counts the options leave unset are one BSDF and two light samples
/// (and the sun's) for every material and vertex: much of a pixel's noise is then the indirect part's, which one
/// continuation per vertex estimates, so the counts by lobe that direct light alone takes spend more time than they
/// remove noise, and one light sample after the camera hit saves less time than it adds noise
/// (docs/RENDERER-INDIRECT.md). Direct light alone (max_depth 1) keeps the counts by lobe.
///
/// Russian roulette. The continuation leaving vertex d (d = 0: the camera ray's hit) is followed for certain when
/// d < kRouletteStartVertex; from there on it survives with probability q = roulette_survival() of the max RGB
/// component of the path's throughput including this bounce's f cos / pdf, and its throughput is divided by q
/// (unbiased: E[1{u < q} / q] = 1). A continuation drawn apart is decided before it is traced; one that is D's
/// BSDF sample is traced anyway (D needs to know whether it escapes) and decided once it hits. Its random number is
/// the next 1D dimension of the pixel's sampler, drawn whenever the rule applies, so pixels stay independent of
/// tiles, threads and crop. max_depth 2 never plays it.
///
/// Regularization (options.regularization = v, 0 = off and unbiased): Cycles' Filter Glossy rule. The path keeps
/// min_pdf, the smallest solid-angle pdf of its non-delta continuation samples so far (infinite at the camera hit).
/// At a later vertex whose min_pdf < v, every lobe narrower than GGX alpha
///   floor = 0.5 sqrt(1 - min_pdf / v)   (Cycles' blur roughness, in alpha; <= 0.5),
/// rounded DOWN to a multiple of kRegularizationStep (regularization_floor()), is widened to the floor, a delta
/// lobe becomes a GGX lobe of the floor (Material::with_roughness_floor()): after a diffuse or rough bounce
/// (small pdf) a near-specular surface is shaded as a rough one, for its direct light and its continuation alike.
/// This is BIASED (the image converges to that of the widened materials: caustics seen through a diffuse bounce
/// are blurred) and trades that bias for much less noise. The camera hit is never widened (min_pdf is infinite
/// there), so directly seen surfaces keep their reflections; neither are measured BRDFs (no roughness to raise).
/// The widened materials are built once when the integrator starts (one per material and floor), and the product
/// tables hold their lobes, so that at a widened vertex every strategy draws exactly as it would for a material of
/// that alpha and weighs by the densities of what it draws: each vertex's estimator is unbiased for the widened
/// material.
///
/// Strategies for D (N BSDF, M light and S sun samples per shading point; N and M by the material's lobe unless the
/// options set them: sample_counts()):
///  - bsdf:  (1/N) sum f cos L / p_bsdf over N BSDF samples.
///  - light: (1/M) sum f cos L V / p_light over M environment samples (light_method: cdf|alias|hierarchical).
///  - mis:   Veach's multi-sample model, N BSDF + M light samples, weights w_i = (n_i p_i)^b / sum_k (n_k p_k)^b,
///           b = 1 (balance) or 2 (power).
///  - mis-compensated: as mis with the light technique drawing from the MIS-compensated table (Karlik et al.
///           2019): max(importance - mean, 0); the compensated pdf enters the weights. Needs N >= 1 (the BSDF
///           technique must cover what the compensated table leaves out).
///  The sun (every strategy but bsdf, S >= 1): when the map has one (sun_split.h), the light technique is two:
///           S samples of the sun's texels and M of the rest of the map (a table of the same method without them).
///           Their densities never overlap, so each is weighted against the BSDF alone (in the weights above, a
///           light sample's n p is that of its own part, a BSDF sample's light term M p_rest + S p_sun). The
///           radiance is the map's in every case: the converged image does not depend on S. Materials whose
///           widest lobe is narrower than GGX alpha kSunSampleAlpha (0.1) keep the whole map's table (the split
///           costs them more than it gains: takes_sun_samples()).
///  - product, product-mis: as light and mis, with the light technique (the whole map's, or the rest of the map
///           beside the sun) replaced by the product table of the point's lobe (lobe_product.h): built once when
///           the integrator starts, for every lobe the scene's materials have (the clamped cosine around the normal
///           for Lambertian and plastic, the GGX reflection lobe of the material's alpha around the mirror
///           direction for rough conductors and for a plastic's coat) and a grid of axes; a shading point draws
///           from the table of its lobe's axis, a plastic's from the mixture of its base's and its coat's tables in
///           the proportion in which its BSDF samples them. The table's (mixture's) pdf enters the weights as any
///           light table's. Uses the hierarchical table.
///  - auto (the default): as mis, with each material's light technique chosen by a pilot when the integrator starts
///           (light_pilot.cpp): its product table or the plain table, the sun apart or not (LightChoice). Shading
///           points of each material are taken where a fixed grid of camera rays first hits it; at each, every
///           candidate's estimate of D is drawn a fixed number of times. A point's score is its relative variance
///           (over its mean squared) times the candidate's cost per shading point (rays, a product table's descent).
///           MIS's own choice (the plain table, the sun by takes_sun_samples()) stands unless another candidate's
///           mean score is lower by more than 1.5 standard errors of the per-point differences. Deterministic
///           (a fixed seed, per-point slots summed in order): the image depends on neither threads, tiles nor crop.
///           Materials the camera does not see, and every material when there is no camera, take product-mis's
///           choice.
///  - product-wavelet, product-wavelet-mis: as light and mis, with M light samples drawn from the shading point's
///           wavelet product of lighting and BSDF x cos (Clarberg et al. 2005; product_wavelet.h), built once when
///           the integrator starts for the scene's materials. The whole map, no sun split (S is not used); the
///           weights are product-mis's. Uses the hierarchical table.
///  - product-steerable, product-steerable-mis: the same with M light samples drawn from the steerable product
///           (Subr and Arvo 2007; product_steerable.h): one lighting table per SH basis function up to band order
///           (8) over a quadtree of R x R (64 x 64) equal-area cells of the sphere, combined with the point's fitted
///           BSDF x cos coefficients, clamped at 0, warped down the quadtree, mixed with 10% of the plain table.
///  - product-sh, product-sh-mis: the same with the SH product of the lighting (projected to SH once) and the
///           point's fitted BSDF x cos (Jarosz, Carr and Jensen 2009; product_sh.h), sampled through the quadtree
///           of its integrals over the cells, with the same mixture. Both: basis_hierarchy.h; options `steerable`
///           and `sh` (BasisProductOptions); built once when the integrator starts; the whole map, no sun split.
/// Random numbers: the M samples of a light technique (and the N BSDF samples) at a shading point draw points k =
/// 0 .. M - 1 of one dimension pair at index sample x M + k (Sampler::point_2d), so that over a pixel's samples
/// they are one stratified sequence of spp x M points.
/// Delta lobes (perfect mirror): no light sample can hit them, so every strategy follows them by BSDF sampling
/// with weight 1 (pure-delta materials take exactly one BSDF sample, whatever N and M say).
/// No NaN or Inf leaves radiance(): a non-finite estimate (never expected) is replaced by 0 and counted.
#include <envkit/core/error.h>
#include <envkit/render/camera.h>
#include <envkit/render/env_light.h>
#include <envkit/render/frame.h>
#include <envkit/render/product_sh.h>
#include <envkit/render/product_steerable.h>
#include <envkit/render/product_wavelet.h>
#include <envkit/render/sampler.h>
#include <envkit/render/scene.h>
#include <envkit/sampling/env_sampling.h>
#include <envkit/sampling/lobe_product.h>
#include <envkit/tables/sun_split.h>

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace envkit::render {

enum class Strategy {
  Bsdf,
  Light,
  Mis,
  MisCompensated,
  Product,
  ProductMis,
  ProductWavelet,
  ProductWaveletMis,
  ProductSteerable,
  ProductSteerableMis,
  ProductSh,
  ProductShMis,
  Auto
};
enum class Heuristic { Balance, Power };

/// Every strategy, in the order help texts and error messages list them.
inline constexpr Strategy kStrategies[] = {Strategy::Auto,
                                           Strategy::Bsdf,
                                           Strategy::Light,
                                           Strategy::Mis,
                                           Strategy::MisCompensated,
                                           Strategy::Product,
                                           Strategy::ProductMis,
                                           Strategy::ProductWavelet,
                                           Strategy::ProductWaveletMis,
                                           Strategy::ProductSteerable,
                                           Strategy::ProductSteerableMis,
                                           Strategy::ProductSh,
                                           Strategy::ProductShMis};

const char* strategy_name(Strategy s);
/// The names of kStrategies joined by `separator` ("auto|bsdf|...").
std::string strategy_names(const std::string& separator);
Strategy parse_strategy(const std::string& name);  ///< throws Error listing the valid names
const char* heuristic_name(Heuristic h);           ///< "balance", "power"
Heuristic parse_heuristic(const std::string& name);

struct IntegratorOptions {
  /// Why this default: BENCHMARKS.md, "The default: a pilot per material".
  Strategy strategy = Strategy::Auto;
  SamplingMethod light_method = SamplingMethod::Hierarchical;
  Heuristic heuristic = Heuristic::Power;
  /// BSDF (N) and light (M) samples per shading point, for every material; unset: by the material's lobe, or
  /// kPathBsdfSamples and kPathLightSamples when max_depth > 1 (sample_counts()).
  std::optional<int> bsdf_samples;
  std::optional<int> light_samples;
  int max_depth = 1;  ///< scattering events per path (1 = direct only)
  /// Samples of the sun's texels per shading point when the map has a sun (sun_split.h); the light samples then
  /// draw from the rest of the map. 0 = no split. Used by every strategy but bsdf, at shading points whose
  /// material takes sun samples (takes_sun_samples(): Lambertian and plastic always).
  int sun_samples = 1;
  /// The product-wavelet strategies' resolution, bins and compression (product_wavelet.h).
  WaveletOptions wavelet;
  /// Path regularization (the file comment): Cycles' Filter Glossy value, finite and >= 0; 0 = unbiased (off).
  /// Biased when > 0. The default, 0.5, was chosen by measurement (docs/RENDERER-INDIRECT.md): up to a few
  /// hundred spp its total error, bias included, is below the unbiased estimator's and below that of Cycles' own
  /// default (1), with half the latter's bias. Only paths with max_depth > 1 are touched; the camera hit and
  /// direct light stay exact.
  double regularization = 0.5;
  /// The product-steerable and product-sh strategies' SH order, quadtree, fits and defensive share (basis_hierarchy.h).
  BasisProductOptions steerable;
  BasisProductOptions sh;
};

/// The IntegratorOptions field a refusal concerns.
enum class IntegratorField {
  Strategy,
  LightMethod,
  BsdfSamples,
  LightSamples,
  SunSamples,
  MaxDepth,
  Regularization,
  WaveletResolution,
  WaveletNormalBins,
  WaveletWoBins,
  WaveletKeptCoefficients,
  SteerableOrder,
  SteerableResolution,
  SteerableWoBins,
  SteerableDefensive,
  ShOrder,
  ShResolution,
  ShWoBins,
  ShDefensive
};

/// The field's name in IntegratorOptions ("max_depth", "wavelet.resolution", "sh.order"): how the library's
/// messages name options.
const char* integrator_field_name(IntegratorField field);

/// Options validate() refuses. The message names the options through a speller, so that each front end shows them
/// its own way (envrender: --max-depth); what() names them by integrator_field_name ("max_depth must be >= 1").
class IntegratorOptionsError : public Error {
 public:
  using Speller = std::function<std::string(IntegratorField)>;
  /// `compose` writes the message with the options spelled by its argument.
  IntegratorOptionsError(IntegratorField at, std::function<std::string(const Speller&)> compose);
  /// The message with every option spelled by `spell`.
  std::string message(const Speller& spell) const { return compose_(spell); }
  IntegratorField field;  ///< the option at fault

 private:
  std::function<std::string(const Speller&)> compose_;
};

/// Throws IntegratorOptionsError unless the options go together: counts that are given are >= 0 and at least what
/// the strategy draws from, max_depth >= 1, sun_samples >= 0, regularization finite and >= 0, the hierarchical
/// table for the product strategies, and the seed samplers' options (wavelet, steerable, sh) within their ranges
/// (out_of_range(), whatever the strategy: "sh.order 20: must be in 1..16"). The Integrator runs it first.
void validate(const IntegratorOptions& options);

/// A lobe is wide when it is at least this GGX alpha (Lambertian counts as 1): it sees much of the sky from a
/// shading point. Materials whose lobes are all wide take the wide sample counts below.
inline constexpr double kWideLobeAlpha = 0.25;
/// Materials whose widest lobe is at least this GGX alpha take sun samples (takes_sun_samples()).
inline constexpr double kSunSampleAlpha = 0.1;
/// Light samples of a wide lobe when the options leave the counts unset (direct light only, max_depth 1).
inline constexpr int kWideLightSamples = 4;
/// A narrow lobe's BSDF and light samples when the options leave the counts unset (direct light only).
inline constexpr int kNarrowBsdfSamples = 4;
inline constexpr int kNarrowLightSamples = 4;
/// Every material's BSDF and light samples when the options leave the counts unset and paths are followed
/// (max_depth > 1), at every vertex (sample_counts()).
inline constexpr int kPathBsdfSamples = 1;
inline constexpr int kPathLightSamples = 2;

/// Russian roulette (the file comment): the first vertex whose continuation may be cut, and the smallest
/// survival probability (bounds the weight 1 / q of a surviving path).
inline constexpr int kRouletteStartVertex = 1;
inline constexpr double kRouletteMinSurvival = 0.05;

/// Russian roulette's survival probability for the continuation leaving vertex `depth` (0 = the camera hit) of a path
/// of at most `max_depth` vertices, whose throughput after this bounce has `throughput` as its largest RGB component:
///   q = clamp(throughput sqrt((depth + 1) / (max_depth - depth - 1)), kRouletteMinSurvival, 1).
/// Why: roulette trades variance for time, and the survival that minimises variance x time (Rath et al. 2022,
/// "EARS") is q = sqrt(S T_a / ((V - S) T_b)): S the second moment of what the continuation brings, V the sample's
/// variance, T_a the sample's cost without the continuation, T_b what a survivor adds. The plain rule q = throughput is
/// that optimum when T_a = T_b; counting cost in shaded vertices (depth + 1 shaded before the decision, at most
/// max_depth - depth - 1 left to a survivor) gives the square root. A survivor near the end of a short path costs
/// little, so roulette cuts less there (the last continuation of a depth-3 path survives with sqrt(2) x throughput):
/// such a continuation often carries caustics (diffuse -> near-specular -> sun), whose variance it would multiply by
/// 1 / q. Deep paths are cut harder at their first decisions, where most of their cost lies ahead. NaN-free: 1 for a
/// non-finite product.
double roulette_survival(double throughput, int depth, int max_depth);
/// Regularization floors are multiples of this GGX alpha (at most kRegularizationMaxFloor, Cycles' largest blur
/// roughness): a few widened materials and product tables instead of one per path.
inline constexpr double kRegularizationStep = 0.125;
inline constexpr double kRegularizationMaxFloor = 0.5;

/// The roughness floor (GGX alpha) at a vertex whose path has min_pdf (the smallest pdf of its non-delta
/// continuation samples, per steradian; infinite at the camera hit) under regularization v: 0.5 sqrt(1 - min_pdf / v)
/// rounded down to a multiple of kRegularizationStep when min_pdf < v, else 0 (no floor). 0 for v = 0.
double regularization_floor(double regularization, double min_pdf);

/// BSDF (N) and light (M) samples per shading point.
struct SampleCounts {
  int bsdf = 1;
  int light = 1;
};
/// The options' counts where set; else, when paths are followed (options.max_depth > 1), kPathBsdfSamples and
/// kPathLightSamples for every material and vertex: much of a pixel's noise is then its indirect light's, estimated
/// by one continuation per vertex, and the counts by lobe spend more time than they remove noise (why:
/// docs/RENDERER-INDIRECT.md, "Sample counts when paths are followed"). Else (direct light only) by the material's
/// lobes. A material whose lobes are all wide (Lambertian,
/// GGX alpha >= kWideLobeAlpha) has the noise of its light samples (and of the shadows): kWideLightSamples light
/// samples and 1 BSDF sample. One with a narrow lobe (a glossy metal, a plastic's glossy coat) sees the sky through
/// a small window that light and BSDF samples find about as well: kNarrowBsdfSamples and kNarrowLightSamples.
/// Powers of two: a pixel's spp x M draws of one technique are the first spp x M points of one (0, 2)-sequence
/// (Sampler::point_2d), evenly stratified when spp and M are powers of two. Pure delta materials take one BSDF
/// sample whatever the counts. Why these numbers: BENCHMARKS.md, "Samples per shading point in powers of two".
SampleCounts sample_counts(const IntegratorOptions& options, const Material& material);

/// Whether a material's shading points draw the sun apart from the rest of the map when the map has a sun: when
/// its widest lobe is at least kSunSampleAlpha (Lambertian and plastic always). Such a lobe sees the sun through its
/// tail from most points, where the sun's own samples find it; a narrower lobe sees it where it reflects it, and its
/// light samples from a table that holds the sun find it there better than one sun sample. Why 0.1: BENCHMARKS.md,
/// "The sun apart for lobes from GGX alpha 0.1".
bool takes_sun_samples(const Material& material);

/// How a material's shading points draw light: from the product table of their lobe or the plain table, and the
/// sun apart from the rest of the map (when it has one) or not.
struct LightChoice {
  bool product = false;
  bool sun_apart = false;
  bool operator==(const LightChoice&) const = default;
};

class Integrator {
 public:
  /// Validates the options (validate(): IntegratorOptionsError) and them against the light (e.g. a missing
  /// compensated table: Error). `camera`: where strategy auto's pilot looks from (only read while constructing).
  Integrator(const Scene& scene, const EnvironmentLight& light, const IntegratorOptions& options,
             const Camera* camera = nullptr);
  ~Integrator();

  /// Radiance along a camera ray.
  Vec3 radiance(const Ray& ray, Sampler& sampler) const;
  /// Direct environment light D(x, wo) leaving a shading point (exposed for tests). frame.n is the shading
  /// normal on the side of wo; geometric_normal is on the same side.
  Vec3 direct(const Vec3& position, const Frame& frame, const Vec3& geometric_normal, const Vec3& wo_local,
              const Material& material, Sampler& sampler) const;

  const IntegratorOptions& options() const { return options_; }
  /// The samples a material takes per shading point (sample_counts()).
  SampleCounts counts(const Material& material) const { return sample_counts(options_, material); }
  /// The sun the light techniques split off (sun_split.h; directions in the tables' frame), or nullptr.
  const SunSplit* sun_split() const { return sun_.get(); }
  /// Whether the product strategies built tables (no: other strategies, or no material with a non-delta lobe).
  bool has_product_tables() const { return product_whole_ || product_split_; }
  /// The number of lobes the product tables were built for (both sets), and the memory they hold (bytes).
  int product_lobe_count() const;
  std::size_t product_table_bytes() const;
  std::size_t nonfinite_count() const { return nonfinite_.load(); }
  /// The light technique of the scene's material `material` (index): the strategy's, or for auto the pilot's.
  LightChoice light_choice(int material) const { return choices_.at(std::size_t(material)); }
  /// The material a vertex shades with under a roughness floor (regularization_floor()): scene material `index`
  /// widened to `floor`, or the scene's own when the floor is 0 or widens none of its lobes.
  const Material& regularized(int index, double floor) const;
  /// The product-wavelet strategies' sampler, or nullptr for other strategies.
  const ProductWavelet* product_wavelet() const { return wavelet_.get(); }
  /// The product-steerable (product-sh) strategies' sampler, or nullptr for other strategies.
  const ProductSteerable* product_steerable() const { return steerable_.get(); }
  const ProductSh* product_sh() const { return sh_.get(); }

  /// A direction StrategyDistribution::sample() draws.
  struct StrategyDraw {
    Vec3 direction;         ///< unit, scene world frame (valid when pdf > 0 or is_delta)
    double pdf = 0.0;       ///< the distribution's density there, per steradian; 0 for a delta draw or none drawn
    bool is_delta = false;  ///< a BSDF sample of a delta lobe (no density)
  };
  struct DrawMix;  ///< StrategyDistribution's techniques (strategy_draw.cpp)
  /// What the strategy draws at one shading point, as one distribution of directions: what envproduct pictures,
  /// and what tests compare a strategy's samples with. Each of the strategy's techniques for the material (the
  /// BSDF's; the light table's parts: the whole map's, or the rest and the sun; its product table; a seed sampler's
  /// product) is picked with probability proportional to its samples per shading point (N, M, S: sample_counts()),
  /// so the density is the one-sample mixture (N p_bsdf + M p_light + S p_sun) / (N + M + S) of the techniques that
  /// direct() draws from. Strategies without BSDF samples (light, product, product-wavelet, ...) leave N out; pure
  /// delta materials draw from the BSDF alone. Light techniques draw over the whole sphere (directions below the
  /// horizon are drawn, and contribute 0 in direct()); a BSDF draw that fails (below the horizon) draws none.
  /// Holds references to the integrator and the material.
  class StrategyDistribution {
   public:
    StrategyDistribution(StrategyDistribution&&) noexcept;
    ~StrategyDistribution();
    /// u: the direction; u_technique in [0, 1): the technique (and, re-uniformised, a BSDF's lobe).
    StrategyDraw sample(Vec2 u, double u_technique) const;
    /// Density per steradian at world direction wi (unit) of sample()'s non-delta draws.
    double pdf(const Vec3& wi_world) const;

   private:
    friend class Integrator;
    StrategyDistribution(const Integrator& integrator, const Frame& frame, const Vec3& wo, const Material& material);
    const Integrator* integrator_;
    Frame frame_;
    Vec3 wo_;
    const Material* material_;
    std::unique_ptr<DrawMix> mix_;
  };
  /// The strategy's distribution at a shading point: `frame.n` the normal, `wo_local` the view in that frame
  /// (z > 0), `material` any (one of the scene's takes its own light choice).
  StrategyDistribution strategy_at(const Frame& frame, const Vec3& wo_local, const Material& material) const;

 private:
  /// What every strategy knows of the point it shades (see direct()).
  struct ShadingPoint {
    Vec3 origin;  ///< the position offset off the surface, for shadow and continuation rays
    const Frame& frame;
    Vec3 ng;  ///< geometric normal on the side of wo
    Vec3 wo;  ///< local frame
    const Material& material;
  };
  /// Where a vertex's estimator of D draws the path's next direction (the file comment): its one BSDF sample, traced
  /// to its first hit. Left with drawn false by estimators that cannot (no BSDF sample, N != 1): the path then
  /// draws its continuation apart.
  struct Continuation {
    bool drawn = false;    ///< the estimator's BSDF sample was traced as the continuation
    bool hit = false;      ///< it hit a surface, `next` (else it escaped, or no direction was drawn)
    Vec3 weight{0, 0, 0};  ///< f cos / pdf of the sample
    double pdf = 0.0;      ///< its solid-angle pdf (regularization's min_pdf); meaningless when is_delta
    bool is_delta = false;
    Ray ray;  ///< the traced ray
    Hit next;
  };
  /// One BSDF sample: value = f cos L V / pdf; pdf 0 when no direction was drawn. light_density: where the
  /// direction escapes, sum over the light techniques of samples x density (what MIS weighs the BSDF against).
  struct BsdfTerm {
    Vec3 value{0, 0, 0};
    Vec3 wi_world;
    double pdf = 0.0;
    double light_density = 0.0;
    bool is_delta = false;
  };
  /// A light table (or mixture of two) drawn `count` times per shading point.
  struct LightTechnique {
    LightTable table;
    int count = 0;
  };
  /// The light techniques of a shading point: the whole map's table, or the rest of the map and the sun (their
  /// densities never overlap).
  struct LightTechniques {
    std::array<LightTechnique, 2> parts{};
    int count = 0;
  };
  /// One light sample: value = f cos L V (not divided by the pdf); black when it contributes nothing.
  struct LightTerm {
    Vec3 value{0, 0, 0};
    Vec3 wi_local;
    double pdf = 0.0;
  };
  /// The random numbers of one BSDF sample: the direction's and the lobe choice's.
  struct BsdfDraw {
    Vec2 u;
    double u_lobe = 0.0;
  };
  /// An estimator of D. `next`: the path wants a continuation from this vertex (nullptr: none, as direct()); the
  /// estimator traces its BSDF sample as that continuation when it draws exactly one, and leaves next->drawn false
  /// otherwise.
  using DirectFn = Vec3 (Integrator::*)(const ShadingPoint&, Sampler&, Continuation* next) const;
  /// StrategyDistribution's techniques at a shading point (strategy_draw.cpp).
  DrawMix draw_mix(const ShadingPoint& x) const;

  double mis_weight(double a, double b) const;
  /// `light`: also find those techniques' density at the direction (MIS), the first in the radiance's texel search.
  /// `next`: trace the sample as the path's continuation (its first hit, not a shadow ray) and record it there.
  BsdfTerm bsdf_term(const ShadingPoint& x, BsdfDraw draw, const LightTechniques* light = nullptr,
                     Continuation* next = nullptr) const;
  /// The continuation an estimator drawing `bsdf_samples` BSDF samples traces: `next`, marked drawn, when it draws
  /// exactly one (it is then the path's next direction), else none (the path draws its own).
  static Continuation* continued_by(Continuation* next, int bsdf_samples);
  /// Whether a BSDF sample's ray reaches the environment: a shadow ray, or with `next` the path's continuation,
  /// whose first hit is recorded there.
  bool escapes(const Ray& ray, const BsdfSample& sample, Continuation* next) const;
  /// D at a path's vertex; with `next`, by the strategy's estimator drawing the continuation where it can.
  Vec3 shade(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  /// The continuation drawn apart from D's estimator (the next sampler dimensions, a BSDF sample of the material,
  /// roulette before the ray is traced); false when the path ends.
  bool continue_apart(const ShadingPoint& x, Sampler& sampler, int depth, Vec3& throughput, double& min_pdf, Ray& ray,
                      Hit& hit) const;
  /// Folds a continuation's f cos / pdf into the path's throughput and plays roulette at vertex `depth`; false when
  /// the path ends (black or non-finite throughput, or roulette).
  bool survives(const Vec3& weight, double pdf, bool is_delta, int depth, Sampler& sampler, Vec3& throughput,
                double& min_pdf) const;
  /// Draw k of the n BSDF samples of a shading point from the two dimension pairs reserved at `dimension`: the n
  /// draws of every sample of a pixel are one stratified sequence (Sampler::point_2d), as are the light draws.
  static BsdfDraw bsdf_draw(const Sampler& sampler, std::uint32_t dimension, int k, int n);
  /// The split when the map has a sun and the material's lobes are wide enough to gain from it, else the whole map.
  /// With product tables, the first part is the table of the material's lobe at this point's axis, or for two lobes
  /// (a plastic) the mixture of their tables in the proportion in which the BSDF samples them. The first part is
  /// drawn `light_samples` times (the material's count, sample_counts()).
  LightTechniques techniques(const ShadingPoint& x, int light_samples, LightChoice choice) const;
  /// The choice of the scene's material at `material`'s address; a material outside the scene gets its strategy's
  /// rule (product tables when built, the sun apart by takes_sun_samples()).
  LightChoice choice_for(const Material& material) const;
  /// Strategy auto: each material's LightChoice from a pilot seen from `camera` (light_pilot.cpp).
  void choose_by_pilot(const Camera& camera);
  /// The lobes the product tables use for a material: [0] its widest (the clamped cosine for materials with a
  /// Lambertian part, the GGX reflection lobe of the material's alpha for rough conductors), [1] its narrowest where
  /// that is another (a plastic's coat); none for pure delta materials.
  static std::array<std::optional<Lobe>, 2> product_lobes(const Material& material);
  /// A lobe's axis at a shading point, world frame: the normal for the cosine, the mirror direction for GGX.
  static Vec3 lobe_axis(const Lobe& lobe, const ShadingPoint& x);
  /// The scene's materials and their widened copies (regularized()): every material a vertex may shade with.
  std::vector<const Material*> shaded_materials() const;
  void build_regularized_materials();
  /// Tables for the lobes of the materials whose choice needs them (widened copies: by product-mis's rule);
  /// `every_lobe`: both sets for every scene material's lobes (the pilot tries every choice).
  void build_product_tables(bool every_lobe);
  /// Validates the product-wavelet options and builds the sampler.
  void build_product_wavelet();
  /// Density of the sun technique at a world direction (0 without a split).
  double sun_pdf(const Vec3& wi_world) const;
  /// The term of light sample `ls` (drawn from the point's light table) at x.
  LightTerm light_term(const ShadingPoint& x, const LightSample& ls) const;
  /// term(j, light_term(x, sample j)) for the t.count light samples of technique t at x in order, sample j drawn
  /// with sampler.point_2d(dimension, j, t.count): drawn a group at a time (EnvironmentLight's batched sample(),
  /// the same samples), so that a product table's descents for the point's samples overlap.
  template <class Term>
  void for_each_light_term(const ShadingPoint& x, const LightTechnique& t, const Sampler& sampler,
                           std::uint32_t dimension, Term&& term) const;
  /// A material's delta lobe (one BSDF sample kept only when it picked that lobe), for strategies whose other
  /// samples cannot reach it; 0 for materials without one (no sample drawn).
  Vec3 delta_lobe_term(const ShadingPoint& x, Sampler& sampler) const;

  // One estimator of D per strategy (see the file comment), chosen once by the constructor (DirectFn).
  Vec3 direct_bsdf(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_light(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  /// mis, mis-compensated, product-mis, auto
  Vec3 direct_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_mis_with(const ShadingPoint& x, Sampler& sampler, LightChoice choice, Continuation* next = nullptr) const;
  Vec3 direct_product_wavelet(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_product_wavelet_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_product_steerable(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_product_steerable_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_product_sh(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  Vec3 direct_product_sh_mis(const ShadingPoint& x, Sampler& sampler, Continuation* next) const;
  /// The shading point's wavelet product (product_wavelet.h).
  ProductWavelet::Point wavelet_point(const ShadingPoint& x) const;
  /// Normal and wo of a shading point in the tables' frame, what the product samplers take.
  Vec3 table_normal(const ShadingPoint& x) const;
  Vec3 table_wo(const ShadingPoint& x) const;
  /// One light sample drawn from a point's product distribution (sample(u) and pdf(direction) in the tables' frame),
  /// as light_term().
  template <class Point>
  LightTerm point_term(const ShadingPoint& x, const Point& p, Vec2 u) const;
  /// M samples of a point's product distribution (and a delta lobe's BSDF sample), or with N BSDF samples under MIS:
  /// the estimators of every product sampler that returns a point.
  template <class Point>
  Vec3 direct_point(const ShadingPoint& x, Sampler& sampler, const Point& p) const;
  template <class Point>
  Vec3 direct_point_mis(const ShadingPoint& x, Sampler& sampler, const Point& p, Continuation* next) const;

  const Scene& scene_;
  const EnvironmentLight& light_;
  IntegratorOptions options_;
  DirectFn direct_ = nullptr;
  std::vector<LightChoice> choices_;  ///< per scene material
  LightTechniques whole_;             ///< the strategy's table of the whole map
  LightTechniques split_;             ///< the rest of the map and the sun, when it has one
  std::shared_ptr<const SunSplit> sun_;
  Vec3 sun_axis_{0, 1, 0};  ///< the sun's direction in the scene's world frame
  /// Product strategies: tables of the scene's lobes over the whole map and over the rest of the map beside the sun
  /// (each for the lobes of the materials that use that table; nullptr when none does).
  std::unique_ptr<LobeProductTables> product_whole_, product_split_;
  std::unique_ptr<ProductWavelet> wavelet_;
  /// Per scene material, its copy widened to floor (k + 1) kRegularizationStep, or nullptr (regularized()).
  std::vector<std::vector<std::unique_ptr<Material>>> regularized_;
  std::unique_ptr<ProductSteerable> steerable_;
  std::unique_ptr<ProductSh> sh_;
  mutable std::atomic<std::size_t> nonfinite_{0};
};

}  // namespace envkit::render
