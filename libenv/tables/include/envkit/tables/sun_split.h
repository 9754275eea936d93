#pragma once
/// @file sun_split.h
/// A map's light sampled in two disjoint parts: the sun's texels and the rest of the map.
///
/// Why: a sun holds a large share of a map's light in a few texels. One table over the whole map spends that share
/// of its samples on the sun and the rest on the sky, at random per sample: a shading point whose one light sample
/// went to the sky misses most of its light, one whose sample went to the sun knows nothing of the sky. Split into
/// the sun's texels (a sparse distribution) and the residual (the same importance with those texels at 0), a renderer
/// draws from each part a fixed number of times per shading point. The two parts never overlap, so in Veach's
/// multi-sample MIS each part is weighted against the BSDF alone. The radiance is not touched: the split changes
/// sampling densities only, never the integrand, so the converged image is the same as without it.
///
/// Why texels and not an analytic disk: a map cannot resolve a sun below its texel size, and drawing the sun's
/// texels by their power keeps L / pdf constant over the sun (a uniform disk does only for a flat disk, and moves
/// light unless its radiance replaces the map's).
#include <envkit/envmap/sun.h>
#include <envkit/sampling/env_sampling.h>
#include <envkit/tables/env_tables.h>

#include <memory>
#include <optional>

namespace envkit {

class SunSplit {
 public:
  /// The split of `tables`' importance on their distribution grid, or nothing when detect_sun (with `options`,
  /// reading the importance as luminance) finds no sun there, or when the sun is all of the map's light (the rest
  /// would be an empty table). The residual is a table of `method`; `compensated`
  /// builds it from max(residual - its solid-angle mean, 0) (Karlik et al. 2019), as the compensated tables are.
  static std::optional<SunSplit> make(const EnvTables& tables, SamplingMethod method, bool compensated,
                                      const SunOptions& options = {});
  /// The same sun over another table of the same `tables`: shares this split's sun, builds the residual of `method`
  /// (a bake that stores the split of each of its tables detects the sun once).
  SunSplit with_method(const EnvTables& tables, SamplingMethod method, bool compensated) const;

  /// The sun on the importance grid, in the tables' frame; power and radiance are importance (luminance).
  const SunEstimate& sun() const { return sun_; }
  /// The sun's texels, each drawn with probability importance x solid angle / the sun's total.
  const SphericalDistribution& sun_distribution() const { return *sun_distribution_; }
  /// The rest of the map: importance 0 on the sun's texels. A table file stores it as a table of its own.
  const StoredTable& residual() const { return *residual_; }
  /// Cosine of the half-angle of a cone about sun().direction that holds every direction of the sun's texels:
  /// sun_distribution()'s pdf is 0 outside it (a test before a texel search).
  double cos_bound() const { return cos_bound_; }

  /// Table files (env_tables.h): the sun (estimate, its texels' distribution, the bound) as one blob; the residual is
  /// saved as a table of its own.
  void save_sun(BlobWriter& out) const;
  /// A split from a save_sun() blob over a width x height `grid` and its residual table, as a table file holds them.
  /// Validates what it reads (a checksum says only that the bytes are as written): Error naming in.context().
  static SunSplit restore(BlobReader& in, Kind grid, int width, int height,
                          std::shared_ptr<const StoredTable> residual);

 private:
  SunSplit() = default;
  /// The sun's part of make(): detection, the sun's texels' distribution and the bound; no residual.
  static std::optional<SunSplit> find(const EnvTables& tables, const SunOptions& options);
  SunEstimate sun_;
  std::shared_ptr<const StoredTable> sun_distribution_;
  std::shared_ptr<const StoredTable> residual_;
  double cos_bound_ = 1.0;
};

}  // namespace envkit
