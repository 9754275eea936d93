#pragma once
/// @file distribution.h
/// The one interface of envkit's 2D sampling distributions: sample(u) -> {uv, pdf}, pdf(uv), invert(uv) -> u.
///
/// Domain and conventions
/// ----------------------
/// A distribution lives on the unit square [0,1)^2 ("uv space") divided into W x H texels: texel (x, y) covers
/// [x/W, (x+1)/W) x [y/H, (y+1)/H), its centre is ((x + 0.5)/W, (y + 0.5)/H). Densities are with respect to uv
/// AREA and constant inside a texel. Cdf, alias and hierarchical distributions are built from a W x H grid of
/// non-negative weights (row-major, row 0 first), sparse ones from the weights of a few texels: a texel of weight
/// w has density w / integral() everywhere inside it, where integral() = sum(w) / (W H). A refined distribution
/// (distribution_refined.h) has no per-texel weights: it multiplies a coarse table with a hierarchical one's sums.
/// Mapping to the sphere (sin theta, texel solid angles) is the job of the layer above: it multiplies the weights
/// by the Jacobian before building and divides pdf_uv by it afterwards.
///
/// Which warp to prefer
/// --------------------
/// Every method is exact in the sense that matters for estimators: pdf(sample(u).uv) == sample(u).pdf bit for
/// bit, and pdf() is the density the tables actually draw from. They differ in how close that is to the ideal
/// w / integral: sparse to double rounding (its densities and cumulative table are stored in double); alias and
/// hierarchical to ~1e-7 / ~1e-6 relative for every texel (pdf() returns w / integral);
/// cdf's pdf() follows its float CDF steps, within (m + c) 2^-24 of the ideal for a texel of marginal m and
/// conditional c (~1e-4 relative for ordinary texels of a 16k row, more for texels far dimmer than their row).
/// - CdfDistribution2D (distribution_cdf.h): marginal CDF over rows + conditional CDF per row, continuous
///   inversion. The smallest tables (~4 bytes/texel), O(log H + log W) per sample, O(1) pdf, invertible. The warp is
///   monotone along each axis, so stratification of u.y survives, but rows are warped independently: around a
///   peak neighbouring u.x strata shear apart. The default when memory matters or when an invertible warp is
///   needed and the map is not too peaky.
/// - AliasDistribution2D (distribution_alias.h): Walker/Vose alias tables, marginal over rows + one per row.
///   O(1) per sample whatever the size, the fastest with plain random numbers on large maps, but the mapping from
///   u to texels is discontinuous everywhere (neighbouring u go to unrelated texels): it destroys stratification,
///   so low-discrepancy sequences gain nothing. Not invertible. Largest tables (16 bytes/texel: one aligned
///   entry per column pick, which also holds the alias's weight).
/// - HierarchicalDistribution2D (distribution_hierarchical.h): a sum pyramid (every node holds the sum of the
///   four below it) with hierarchical sample warping (Clarberg et al. 2005). The warp is continuous inside every
///   quadtree cell, so it preserves the stratification of Sobol or other low-discrepancy points best (lowest
///   variance per sample with QMC), and it is the structure that product sampling with a BSDF quadtree descends
///   (Clarberg 2008). O(log max(W,H)) per sample, O(1) pdf,
///   invertible, ~5.3 bytes/texel. Every node stores its own sum, so probabilities keep float RELATIVE precision
///   even for texels a billion times dimmer than the sun next to them.
/// - SparseDistribution2D (distribution_sparse.h): light on a few texels of a large grid (a sun's texels, see
///   sun_split.h); one cumulative table over those texels, nothing per texel of the grid. O(log n), invertible.
/// - RefinedDistribution2D (distribution_refined.h): a hierarchical warp over the nodes of one level of a
///   hierarchical distribution, continued below the chosen node by that distribution's own sums (product sampling).
///   Built at load from the distribution it refines, never stored.
/// Cdf, alias, hierarchical and sparse distributions are StoredDistribution2D: table files hold them.
/// (Mitsuba 3's distr_2d.h documents the same trade-off between its hierarchical and marginal warps.)
///
/// Random numbers
/// --------------
/// u is taken in [0,1)^2 and clamped internally; values outside (and NaN) are clamped, never propagated.
/// Every discrete decision (bin, coin flip, child) re-uniformises the part of u it did not use, and every
/// re-uniformised value is clamped again to [0, kOneMinusEpsilon]: rounding may otherwise push it to 1 and pick a
/// bin that does not exist. The fraction left for the position inside the chosen texel is clamped to
/// [0, kTexelOffsetMax] so that the returned uv stays strictly inside texel (x, y) after rounding (W, H < 2^24).
/// Each decision consumes bits of u: feed 53-bit doubles (not float-derived u) so that tiny probabilities are
/// reachable: a 24-bit u cannot select a bin whose probability is below 2^-24 of its parent's.
///
/// Precision: tables are accumulated in double and stored in float. A float running sum stops growing once an
/// addend is below half an ulp of the sum, i.e. texels below ~2^-24 of the running sum get zero CDF steps and are
/// never sampled although their weight says otherwise (and a long tail of such texels vanishes together). Double
/// accumulation keeps every partial sum exact to ~1e-16; each stored float is then rounded once, on its own.
#include <envkit/core/error.h>
#include <envkit/core/table_blob.h>
#include <envkit/core/vec.h>

#include <algorithm>
#include <cfloat>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace envkit {

/// Largest double below 1: every discrete decision uses u clamped to [0, kOneMinusEpsilon]. (Not 1 - 2^-24: with
/// double u that would make the top 2^-24 of every re-uniformised range unreachable, i.e. a texel whose share of
/// its parent is below 2^-24 and sits after the bright part could never be drawn.)
inline constexpr double kOneMinusEpsilon = 0x1.fffffffffffffp-1;
/// 1 - 2^-24, the largest float below 1: bound of the offset inside the chosen texel, wide enough that
/// (x + offset) / W never rounds up to the next texel for W < 2^24.
inline constexpr double kTexelOffsetMax = 0x1.fffffep-1;
/// Largest width or height a distribution accepts (see kTexelOffsetMax).
inline constexpr int kMaxDistributionSize = 1 << 24;

/// envkit's distribution classes, as Distribution2D::builtin() names them. The classes are final: the class named
/// is the object's type.
enum class BuiltinDistribution { Other, Cdf, Alias, Hierarchical, Sparse, Refined };

/// One sample drawn from a Distribution2D.
struct DistributionSample {
  Vec2 uv{0.0, 0.0};  ///< position in [0,1)^2, strictly inside texel (x, y)
  double pdf = 0.0;   ///< density w.r.t. uv area; exactly pdf(uv); > 0 for any drawn sample
  int x = 0;          ///< column of the texel the sample lies in
  int y = 0;          ///< row of the texel the sample lies in
};

/// The texel a Distribution2D chose and the position inside it, before uv is formed: what layers that map texels
/// themselves (SphericalDistribution) need. sample(u) is exactly {((x + fx) / W, (y + fy) / H), pdf, x, y}.
struct TexelSample {
  double fx = 0.0;   ///< offset inside the texel along x, in [0, kTexelOffsetMax]
  double fy = 0.0;   ///< offset inside the texel along y, in [0, kTexelOffsetMax]
  double pdf = 0.0;  ///< as DistributionSample::pdf
  int x = 0;
  int y = 0;
};

/// A 2D distribution over the W x H texels of the unit square (see the file comment for conventions).
/// Implementations are immutable after construction and safe to use from many threads at once.
class Distribution2D {
 public:
  virtual ~Distribution2D() = default;
  Distribution2D(const Distribution2D&) = default;
  Distribution2D& operator=(const Distribution2D&) = default;
  Distribution2D(Distribution2D&&) = default;
  Distribution2D& operator=(Distribution2D&&) = default;

  /// "cdf", "alias", "hierarchical", "sparse" or "refined".
  virtual const char* method() const = 0;
  /// Which of envkit's classes this is (BuiltinDistribution::Other for classes defined elsewhere): lets a caller
  /// that inlines a class's non-virtual pick() choose it without RTTI.
  virtual BuiltinDistribution builtin() const { return BuiltinDistribution::Other; }

  /// Warp u in [0,1)^2 to a sample. Deterministic: identical tables and u give bit-identical results.
  virtual DistributionSample sample(Vec2 u) const = 0;

  /// sample(u) without forming uv: the same texel, pdf and offsets (sample(u).uv = ((x + fx) / W, (y + fy) / H)).
  /// The built-in distributions compute it directly; this default recovers the offsets from sample(u).uv.
  virtual TexelSample sample_texel(Vec2 u) const {
    const DistributionSample s = sample(u);
    TexelSample t;
    t.fx = std::clamp(s.uv.x * width_ - s.x, 0.0, kTexelOffsetMax);
    t.fy = std::clamp(s.uv.y * height_ - s.y, 0.0, kTexelOffsetMax);
    t.pdf = s.pdf;
    t.x = s.x;
    t.y = s.y;
    return t;
  }

  /// sample_texel(u[k]) into out[k] for every k, bit for bit (u.size() == out.size(), checked by the caller). On
  /// tables larger than the caches one sample is a chain of dependent misses; the built-in distributions override
  /// this with warps that take the samples in groups of sampling::kSampleGroup and run each step of the chain for
  /// the whole group, prefetching the next step's table entries, so that the group's misses overlap instead of
  /// following one another. On CPUs with AVX-512 the cdf and hierarchical warps run each step eight samples per vector,
  /// with masks instead of their unpredictable branches (the same operations, so the same bits; ENVKIT_SIMD=none
  /// turns the vector paths off). This default is the plain loop.
  virtual void sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const {
    for (std::size_t k = 0; k < u.size(); ++k) out[k] = sample_texel(u[k]);
  }

  /// Density w.r.t. uv area at uv: the density of the texel containing uv. uv on the closed square [0,1]^2 is
  /// accepted (1.0 belongs to the last texel, as to_uv() of a pole may return it); 0 outside and for NaN.
  /// Never inf or NaN.
  virtual double pdf(Vec2 uv) const = 0;

  /// The probability the stored (float) tables actually give texel (x, y), recomputed from them in double:
  /// what sample() draws, to be compared with the ideal w / sum(w). 0 for texels outside the grid.
  /// Cost: O(1) for cdf, O(levels) for hierarchical, O(W + H) for alias (a diagnostic, not for render loops).
  virtual double texel_probability(int x, int y) const = 0;

  /// Whether invert() is available (cdf, hierarchical, sparse: yes; alias, refined: no).
  virtual bool can_invert() const { return false; }

  /// The u that sample() maps to uv: invert(sample(u).uv) == u up to rounding wherever the texel has non-zero
  /// probability. uv is clamped to [0,1]^2 (NaN -> 0). Throws Error when can_invert() is false.
  virtual Vec2 invert(Vec2 /*uv*/) const {
    throw Error(std::string(method()) + " distribution: invert() is not supported (can_invert() is false)");
  }

  /// Memory held by the tables, in bytes.
  virtual std::size_t bytes() const = 0;

  int width() const { return width_; }
  int height() const { return height_; }

  /// sum(weights) x texel area (1 / (W H)), accumulated in double over the sanitised weights: the normaliser of
  /// pdf. 0 for an all-zero map (which then samples uniformly, see used_uniform_fallback()).
  double integral() const { return integral_; }

  /// True when every weight was zero (or invalid): the distribution is then uniform over [0,1)^2 and pdf() is 1
  /// everywhere. Tools should warn: the map carries no light.
  bool used_uniform_fallback() const { return uniform_fallback_; }

  /// Rows whose weights are all zero and whose conditional table (cdf, alias) was therefore made uniform.
  /// Such rows have zero marginal probability: they are never sampled (pdf is 0 there) unless the whole map is
  /// zero; the uniform conditional only gives invert() a defined answer. Always 0 for the hierarchical method.
  int uniform_fallback_rows() const { return fallback_rows_; }

  /// Texels with positive weight to which the float tables give zero probability (cdf only: a bin below the
  /// float resolution of its CDF entries; see distribution_cdf.h). pdf() is 0 there too, so estimators stay
  /// consistent, but that light can only be found by other strategies (BSDF sampling under MIS).
  std::size_t unreachable_texels() const { return unreachable_texels_; }

 protected:
  /// Validates the size (1..kMaxDistributionSize each); throws Error otherwise.
  Distribution2D(int width, int height) : width_(width), height_(height) {
    if (width < 1 || height < 1 || width > kMaxDistributionSize || height > kMaxDistributionSize)
      throw Error("distribution: invalid size " + std::to_string(width) + "x" + std::to_string(height) +
                  " (each side must be in 1.." + std::to_string(kMaxDistributionSize) + ")");
  }
  /// Fields left to a derived constructor that sets them all (StoredDistribution2D's restore).
  Distribution2D() = default;

  int width_ = 0;
  int height_ = 0;
  double integral_ = 0.0;
  bool uniform_fallback_ = false;
  int fallback_rows_ = 0;
  std::size_t unreachable_texels_ = 0;
};

/// A distribution that table files store (env_tables.h): cdf, alias, hierarchical and sparse.
class StoredDistribution2D : public Distribution2D {
 public:
  /// Writes the tables as a flat blob (table_blob.h). Each class restores it with its BlobReader constructor; a
  /// restored distribution samples bit-identically to the saved one.
  virtual void save(BlobWriter& out) const = 0;

 protected:
  using Distribution2D::Distribution2D;

  /// Restores the fields of Distribution2D written by save_base(); validates the size like its constructor.
  explicit StoredDistribution2D(BlobReader& in) {
    width_ = in.scalar<std::int32_t>();
    height_ = in.scalar<std::int32_t>();
    integral_ = in.scalar<double>();
    uniform_fallback_ = in.scalar<std::int32_t>() != 0;
    fallback_rows_ = in.scalar<std::int32_t>();
    unreachable_texels_ = static_cast<std::size_t>(in.scalar<std::uint64_t>());
    if (width_ < 1 || height_ < 1 || width_ > kMaxDistributionSize || height_ > kMaxDistributionSize ||
        !(integral_ >= 0.0) || fallback_rows_ < 0 || fallback_rows_ > height_)
      throw Error(in.context() + ": invalid distribution header");
  }
  void save_base(BlobWriter& out) const {
    out.scalar<std::int32_t>(width_);
    out.scalar<std::int32_t>(height_);
    out.scalar<double>(integral_);
    out.scalar<std::int32_t>(uniform_fallback_ ? 1 : 0);
    out.scalar<std::int32_t>(fallback_rows_);
    out.scalar<std::uint64_t>(unreachable_texels_);
  }
};

/// Small helpers shared by the implementations (and handy for callers writing their own warps).
namespace sampling {

/// The check of every constructor that takes a W x H weight array (after the base class checked the size): Error
/// when it is null.
inline void require_weights(const float* weights) {
  if (weights == nullptr) throw Error("distribution: null weights");
}

/// Weight as the tables see it: negative, -0 and NaN become 0, +inf becomes FLT_MAX (very bright, but finite).
inline float sanitize_weight(float w) { return w > 0.0f ? std::min(w, FLT_MAX) : 0.0f; }

/// v clamped to [0, hi]; NaN and -0 -> +0. (SSE2: maxsd returns its second operand when either is NaN, so
/// max(v, +0) maps NaN, negatives and -0 to +0 without a branch.)
inline double clamp_unit(double v, double hi) {
#if defined(__SSE2__)
  return _mm_cvtsd_f64(_mm_min_sd(_mm_max_sd(_mm_set_sd(v), _mm_setzero_pd()), _mm_set_sd(hi)));
#else
  return v > 0.0 ? std::min(v, hi) : 0.0;
#endif
}

/// Samples per group of the batched warps (Distribution2D::sample_texels): enough misses in flight to fill a
/// core's miss buffers several times over, few enough that a group's per-sample state stays in L1.
inline constexpr std::size_t kSampleGroup = 64;

/// Calls f(first, count) for consecutive groups of at most `group` (kSampleGroup) of n items.
template <class F>
inline void for_each_group(std::size_t n, F&& f, std::size_t group = kSampleGroup) {
  for (std::size_t g = 0; g < n; g += group) f(g, std::min(group, n - g));
}

/// Samples per group of the draws of one shading point taken together (a product table's few light samples,
/// SphericalDistribution::sample_each): their descents interleaved fill the pipeline; a group's per-sample state is
/// set up for each point, so it is kept to what a point draws.
inline constexpr std::size_t kDrawGroup = 8;

/// u clamped to [0, kOneMinusEpsilon]; NaN -> 0.
inline double clamp_decision(double u) { return clamp_unit(u, kOneMinusEpsilon); }

/// Offset inside a texel clamped to [0, kTexelOffsetMax]; NaN -> 0.
inline double clamp_offset(double f) { return clamp_unit(f, kTexelOffsetMax); }

/// Texel index along an axis of n texels for a coordinate t in [0,1]; 1.0 maps to n - 1. The caller checks
/// the range first.
inline int texel_index(double t, int n) { return std::min(static_cast<int>(t * n), n - 1); }

/// True if uv lies in the closed unit square (false for NaN).
inline bool in_unit_square(Vec2 uv) { return uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0; }

/// uv clamped into [0,1]^2, NaN -> 0.
inline Vec2 clamp_uv(Vec2 uv) {
  return Vec2(uv.x > 0.0 ? std::min(uv.x, 1.0) : 0.0, uv.y > 0.0 ? std::min(uv.y, 1.0) : 0.0);
}

}  // namespace sampling

}  // namespace envkit
