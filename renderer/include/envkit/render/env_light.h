#pragma once
/// @file env_light.h
/// The environment as a light: radiance lookup and sampling through envkit's baked tables.
///
/// Frames. The tables hold directions in the environment map's WORLD frame (the bake applied the map's
/// convention and rotation). The scene may rotate the environment further: world_scene = R table_dir, with
/// R = rotation_from_euler_degrees(yaw, pitch, roll) (convention.h). Radiance is scaled by `intensity`.
///
/// Radiance lookup. The map is brought onto the tables' bake grid (an envkit-canonical lat-long, an
/// equal-area octahedral or a HEALPix map of grid_width x grid_height): used as is when it already is that grid with an
/// identity map->world transform, else resampled with libenv's flux-conserving area filter. Lookup takes the
/// NEAREST texel of that grid, so L / pdf is constant inside each texel (no fireflies from a filtered lookup
/// that the importance does not cover). When the distribution is that grid, light samples use their drawn
/// texel directly; when it is coarser (baked with --resolution), each distribution texel covers several
/// radiance texels (L / pdf is then constant per radiance texel) and radiance is looked up by direction.
#include <envkit/core/huge_page_allocator.h>
#include <envkit/core/vec.h>
#include <envkit/envmap/envmap.h>
#include <envkit/sampling/env_sampling.h>
#include <envkit/tables/env_tables.h>

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace envkit::render {

/// A direction drawn by EnvironmentLight::sample(). Its radiance is EnvironmentLight::radiance(sample): a separate
/// read, so that a caller can trace the shadow ray while the texel, prefetched by sample(), arrives from memory.
struct LightSample {
  Vec3 direction;         ///< unit, scene world frame
  double pdf = 0;         ///< per steradian
  std::size_t texel = 0;  ///< the radiance texel the direction lies in (row-major index into the radiance grid)
};

/// What a light sample is drawn from: one of the light's distributions, or a mixture of two over the same grid (a
/// shading point whose BSDF has two lobes, each with its own product table): with probability `second_share` from
/// `second`, else from `first`; the density is the mixture's, (1 - s) p_first + s p_second. Implicit from one
/// distribution.
struct LightTable {
  LightTable() = default;
  LightTable(const SphericalDistribution& distribution) : first(&distribution) {}  // NOLINT: implicit by design
  LightTable(const SphericalDistribution& a, const SphericalDistribution& b, double share_of_b)
      : first(&a), second(&b), second_share(share_of_b) {}
  const SphericalDistribution* first = nullptr;
  const SphericalDistribution* second = nullptr;  ///< nullptr: `first` alone
  double second_share = 0.0;                      ///< in [0, 1] (clamped; NaN draws from `first` alone)
};

class EnvironmentLight {
 public:
  /// `tables` must have been baked from `map` (checked by the caller through the source hash).
  EnvironmentLight(const EnvMap& map, std::shared_ptr<const EnvTables> tables, const Mat3& rotation = identity3(),
                   double intensity = 1.0);

  /// Radiance seen in world direction d (unit), nearest texel.
  Vec3 radiance(const Vec3& d) const;
  /// The distribution of a method (compensated twin when `compensated`); throws Error naming what is missing.
  const SphericalDistribution& distribution(SamplingMethod method, bool compensated) const;
  /// Draws a direction from `table` (this light's distributions; a mixture's two over one grid, else Error) and
  /// prefetches its radiance texel. A mixture spends u.x on the choice, re-uniformised, so that stratified u stay
  /// stratified within each distribution.
  LightSample sample(const LightTable& table, Vec2 u) const;
  /// sample(table, u[k]) into out[k] for every k, bit for bit: a shading point's light samples drawn together, so
  /// that product tables descend for all of them at once (SphericalDistribution::sample_each). Throws Error unless
  /// the spans have one size.
  void sample(const LightTable& table, std::span<const Vec2> u, std::span<LightSample> out) const;
  /// Radiance of a sample's texel (RGB, intensity applied): radiance(s.direction), without the search.
  Vec3 radiance(const LightSample& s) const { return texels_[s.texel].rgb(); }
  /// Density per steradian of world direction d under `table`.
  double pdf(const LightTable& table, const Vec3& d) const;
  /// The sample of world direction d (unit) as sample() would return it had it drawn d: its texel, prefetched, and
  /// pdf(table, d), with one texel search where the distributions are on the radiance grid. A BSDF sample looks
  /// its direction up before its shadow ray and reads radiance() after it.
  LightSample lookup(const LightTable& table, const Vec3& d) const;
  /// lookup() without a distribution: the texel of d, prefetched; pdf 0.
  LightSample lookup(const Vec3& d) const;

  const EnvTables& tables() const { return *tables_; }
  const Mat3& rotation() const { return rotation_; }
  /// A world direction in the tables' frame (the inverse of rotation()).
  Vec3 to_table(const Vec3& d) const { return apply(inverse_rotation_, d); }
  double intensity() const { return intensity_; }
  /// Mean radiance over the sphere per channel (intensity applied), for reports and tests.
  Vec3 mean_radiance() const;

 private:
  std::shared_ptr<const EnvTables> tables_;
  const SphericalDistribution* lookup_ = nullptr;  // any baked distribution: gives texel_of for the grid
  Mat3 rotation_;
  Mat3 inverse_rotation_;
  double intensity_ = 1.0;
  int width_ = 0, height_ = 0;                       // radiance grid (the tables' bake grid)
  std::unique_ptr<Parameterization> radiance_grid_;  // set when finer than the distribution (--resolution)
  /// One texel's RGB (intensity applied), 16 bytes: a lookup reads one aligned cache line, never two. Float: the
  /// map's own precision.
  struct alignas(16) Texel {
    float r = 0.0f, g = 0.0f, b = 0.0f;
    Vec3 rgb() const { return Vec3(r, g, b); }
  };
  std::vector<Texel, HugePageAllocator<Texel>> texels_;  // the radiance grid, row-major (huge pages: fewer faults)
  /// Index into texels_ of texel (x, y), clamped to the grid; of the texel holding a direction of the tables' frame.
  std::size_t texel_index(int x, int y) const;
  std::size_t texel_index(const Vec3& table_dir) const;
  /// The share of `second` in a mixture, in [0, 1]: 0 for a single distribution (and NaN).
  static double second_share(const LightTable& table);
  /// s with its texel set to `texel`, which is prefetched: what sample() and lookup() return.
  LightSample prefetched(LightSample s, std::size_t texel) const;
  /// The light sample of a draw `ds` from `table` (of second share `share`): its world direction, the table's (the
  /// mixture's) density, its radiance texel prefetched.
  LightSample drawn(const LightTable& table, double share, const DirectionSample& ds) const;
};

/// Loads `tables_path` and checks it against `map` (stale or missing tables are errors naming the file, with
/// a hint to pass --bake), or, when `bake` is true, bakes every method plus the compensated twins in memory.
/// `note` receives a line for the user when something was baked.
std::shared_ptr<const EnvTables> load_or_bake_tables(const EnvMap& map, const std::string& image_path,
                                                     const std::string& tables_path, bool bake, std::string* note);

}  // namespace envkit::render
