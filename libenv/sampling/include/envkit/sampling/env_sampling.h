#pragma once
/// @file env_sampling.h
/// Sampling directions on the sphere from a 2D distribution baked over a lat-long, equal-area octahedral or HEALPix
/// grid.
///
/// One interface for every method (cdf, alias, hierarchical): sample(u) -> {direction, pdf per steradian, texel},
/// pdf(direction), invert(direction) -> u (cdf and hierarchical).
///
/// Frame: directions are unit vectors in the frame the tables were baked in (envkit's canonical world frame,
/// +Y up, see latlong.h / octahedral.h / healpix.h; the bake has already applied the source map's convention and
/// rotation).
///
/// Density inside a texel. The 2D distribution picks texel (x, y) with probability P(x, y) = w / sum(w), where
/// w = importance x exact texel solid angle Omega(x, y). The position inside the texel is then drawn UNIFORMLY IN
/// SOLID ANGLE (lat-long: longitude linear in the offset, z = cos theta linear in the offset between the row's
/// bounds; octahedral: the map is equal-area, so uniform in the square is uniform in solid angle; HEALPix: every
/// texel is one HEALPix pixel whose face coordinates map to the sphere with a constant Jacobian (healpix.h), so
/// uniform in the texel is uniform in solid angle too; offsets are kept HealpixMap::to_image_tolerance() texels
/// away from the edges so that texel_of() finds every sample in its own texel). The density is therefore constant
/// per texel:
///     pdf(direction) = P(x, y) / Omega(x, y)  = importance(x, y) / sum(importance x Omega)
/// This is the seed's pdf_uv / (2 pi^2 sin theta) done right: the sin theta is integrated over the texel, so the
/// pdf is finite at the poles (sin theta = 0) instead of infinite, and it is never NaN. It is 0 exactly where the
/// importance is 0. Radiance looked up with the nearest texel of the bake grid makes L / pdf constant inside a
/// texel.
///
/// Cost: on lat-long grids sample() runs no trigonometric function (per-row cos theta bounds, a longitude table
/// of sin/cos with an angle addition inside the step, see env_sampling.cpp), and the built-in distributions'
/// texel choice is inlined into it (one indirect call per sample, chosen at construction).
///
/// u: any value is accepted and clamped to [0, 1) at every level (see distribution.h). Thread-safe, immutable.
#include <envkit/core/vec.h>
#include <envkit/maps/parameterization.h>
#include <envkit/sampling/distribution.h>

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace envkit {

class HealpixMap;  // healpix.h

/// The three warps of distribution.h under their user-facing names.
enum class SamplingMethod { Cdf, Alias, Hierarchical };

/// "cdf", "alias", "hierarchical".
const char* method_name(SamplingMethod method);
/// Accepts "cdf", "alias", "hierarchical" (or "pyramid"); throws Error otherwise.
SamplingMethod parse_method(const std::string& name);

/// One direction drawn from a SphericalDistribution.
struct DirectionSample {
  Vec3 direction{0.0, 1.0, 0.0};  ///< unit vector, table frame
  double pdf = 0.0;               ///< density per steradian; equals pdf(direction); > 0 for a drawn sample
  int x = 0;                      ///< texel column of the bake grid
  int y = 0;                      ///< texel row of the bake grid (row 0 = top, +Y for lat-long)
};

/// A Distribution2D over a lat-long (2:1 or any W x H), equal-area octahedral (square) or HEALPix (4 N_side x 3 N_side,
/// healpix.h's layout) grid, seen as a density over directions.
class SphericalDistribution {
 public:
  /// grid: Kind::LatLong (envkit canonical, centre-sampled), Kind::Octahedral or Kind::HEALPix; the distribution's
  /// size is the grid's. Its weights must be importance x texel solid angle (see the file comment). Throws Error for
  /// another kind, a non-square octahedral grid or a HEALPix grid that is not 4 N_side x 3 N_side.
  SphericalDistribution(Kind grid, std::shared_ptr<const Distribution2D> distribution);
  /// A distribution over the same grid as `same_grid` (the same size; throws Error otherwise), sharing its
  /// precomputed geometry (row bands, longitude table: tens of kilobytes per grid and more), so that many
  /// distributions over one grid cost only their own tables (product tables, lobe_product.h).
  SphericalDistribution(const SphericalDistribution& same_grid, std::shared_ptr<const Distribution2D> distribution);

  /// Warp u in [0,1)^2 to a direction.
  DirectionSample sample(Vec2 u) const { return sample_(*this, u); }
  /// sample(u[k]) into out[k] for every k, bit for bit; throws Error unless u.size() == out.size(). For many
  /// samples: on tables larger than the caches each sample is a chain of dependent cache misses, which this runs
  /// for groups of samples at a time so that the misses of a group overlap (the texel choice through
  /// Distribution2D::sample_texels, then the group's row bands and longitude entries, prefetched).
  void sample(std::span<const Vec2> u, std::span<DirectionSample> out) const;
  /// from[k]->sample(u[k]) into out[k] for every k, bit for bit: the few draws of one shading point, each from its
  /// own distribution (a mixture's). Distributions over one lat-long grid that are product tables of one set
  /// (RefinedDistribution2D::pick_group) draw together, their descents interleaved; others one by one. Throws Error
  /// unless the three spans have one size.
  static void sample_each(std::span<const SphericalDistribution* const> from, std::span<const Vec2> u,
                          std::span<DirectionSample> out);
  /// Density per steradian at direction (need not be normalised; 0 for a zero or NaN vector).
  double pdf(const Vec3& direction) const;
  bool can_invert() const { return distribution_->can_invert(); }
  /// The u that sample() maps to direction (within rounding). Throws Error for alias.
  Vec2 invert(const Vec3& direction) const;

  /// Texel of the bake grid containing direction (lat-long row from theta, column from longitude). On lat-long
  /// grids without trigonometry: a polynomial arctangent guesses the row and column, and comparisons with the
  /// row edges' cos theta and the column edges' sin / cos (the sampler's longitude table) settle them exactly.
  void texel_of(const Vec3& direction, int& x, int& y) const;
  /// Density per steradian of every direction inside texel (x, y) (in the grid): pdf(d) for d in that texel.
  double texel_pdf(int x, int y) const;
  /// Exact solid angle of texel (x, y), steradians (HEALPix: 4 pi / (12 N_side^2) for every texel).
  double texel_solid_angle(int x, int y) const;

  Kind grid() const { return grid_; }
  int width() const { return distribution_->width(); }
  int height() const { return distribution_->height(); }
  const Distribution2D& distribution() const { return *distribution_; }
  std::shared_ptr<const Distribution2D> distribution_ptr() const { return distribution_; }

  /// Direction of fractional position (fx, fy) in [0,1)^2 inside texel (x, y): the warp sample() applies after
  /// the 2D distribution chose the texel, uniform in solid angle inside the texel. For warps that choose texels
  /// themselves (product sampling). Arguments outside the grid or [0, 1) (and NaN) are clamped into it.
  Vec3 direction_in_texel(int x, int y, double fx, double fy) const;

 private:
  /// Inverse of direction_in_texel: texel and fractional position of direction.
  void locate(const Vec3& direction, int& x, int& y, double& fx, double& fy) const;

  /// A lat-long row measured from its nearer pole (full precision near the poles, where cos theta is within an
  /// ulp of +-1): start = 1 - cos theta0 (north) or 1 + cos theta1 (south), span = cos theta0 - cos theta1.
  /// At offset fy the distance from the pole is start + (g0 + gs fy) span (fy north, 1 - fy south) and
  /// cos theta = gs (1 - that distance). pdf_factor = 1 / (W H texel solid angle): pdf per steradian over pdf_uv.
  /// One cache line per row.
  struct alignas(64) RowBand {
    double start = 0.0;
    double span = 0.0;
    double pdf_factor = 0.0;
    double g0 = 0.0;  // 0 north, 1 south
    double gs = 1.0;  // +1 north, -1 south
    bool north() const { return gs > 0.0; }
  };
  static RowBand row_band(int y, int height);

  /// sin a and -cos a of the angle a = 2 pi k / N at the start of step k of the longitude table
  /// (lon = pi - a: sin lon = sin a, cos lon = -cos a).
  struct Longitude {
    double sin_a = 0.0;
    double minus_cos_a = -1.0;
  };
  /// kOneStep: the longitude table has one step per column (W >= 2048), else longitude_substeps_ per column.
  template <bool kOneStep>
  Vec3 latlong_direction(const RowBand& band, int x, double fx, double fy) const;
  /// The directions of a group of chosen texels on a lat-long grid (the batched sample()'s last stage).
  template <bool kOneStep>
  void latlong_directions(const TexelSample* t, DirectionSample* out, std::size_t n) const;
  /// sample() through the virtual sample_texel(): octahedral and HEALPix grids, and distributions other than the
  /// built-ins.
  static DirectionSample sample_general(const SphericalDistribution& s, const Vec2& u);
  /// sample() on a lat-long grid with a built-in distribution D: its inline pick(), no virtual call.
  template <class D, bool kOneStep>
  static DirectionSample sample_latlong(const SphericalDistribution& s, const Vec2& u);

  Kind grid_;
  BuiltinDistribution builtin_ = BuiltinDistribution::Other;  // distribution_'s class, for texel_pdf()
  std::shared_ptr<const Distribution2D> distribution_;
  /// What sample() runs, chosen at construction (sample_latlong<D, ...> or sample_general): one indirect call.
  DirectionSample (*sample_)(const SphericalDistribution&, const Vec2&) = &sample_general;
  /// The grid's geometry, shared by every distribution over the same grid (see the constructor that takes one).
  struct Geometry {
    std::vector<RowBand> rows;  // lat-long: per row, precomputed (no trigonometry per sample)
    /// Lat-long: cos theta of the row edges, H + 1 values from 1 down to -1 (texel_of's exact row test).
    std::vector<double> row_edge_cos;
    /// Lat-long: N = W x longitude_substeps steps of the angle a = 2 pi (x + fx) / W (lon = pi - a), at least
    /// kMinLongitudeSteps so that a step is small enough for short sin/cos polynomials (env_sampling.cpp);
    /// N + 1 entries.
    std::vector<Longitude> longitudes;
    int longitude_substeps = 1;
    double sin_poly[3] = {};  // sin d and cos d - 1 for d = f 2 pi / N, polynomials in f in [0, 1)
    double cos_poly[2] = {};
    /// Equal-area grids (octahedral, HEALPix): pdf per steradian over pdf_uv, 1 / (W H texel solid angle) = 1 / (4 pi).
    double equal_area_pdf_factor = 0.0;
    /// HEALPix grids: the map whose texel <-> direction functions place samples (its geometry lives in one place).
    std::shared_ptr<const HealpixMap> healpix;
    /// HEALPix grids: offsets inside a texel are kept in [margin, 1 - margin] (HealpixMap::to_image_tolerance), so
    /// that texel_of() locates every sample in the texel it was drawn from (pdf and radiance agree with the sample).
    double healpix_margin = 0.0;
  };
  static std::shared_ptr<const Geometry> make_geometry(Kind grid, int width, int height);
  /// Sets sample_ for the grid and the distribution's class.
  void choose_sampler();
  std::shared_ptr<const Geometry> geometry_;
  const Geometry* g_ = nullptr;  // geometry_.get()
};

}  // namespace envkit
