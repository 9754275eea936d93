#pragma once
/// @file lobe_product.h
/// Product tables: the environment's importance times a lobe, precomputed once per environment for every lobe
/// shape a scene needs and a grid of lobe axes, so that a shading point draws from (approximately) its BSDF x
/// environment product at the cost of one table choice and one hierarchical descent.
///
/// A lobe is a function of the cosine between a direction and its axis: the clamped cosine (a Lambertian surface,
/// axis = the normal) or the reflected lobe of an isotropic GGX of roughness alpha (axis = the mirror direction),
/// D(h) / 4 with h halfway between the axis and the direction: the density of directions that GGX visible-normal
/// sampling reflects at normal incidence (it integrates to 1), without masking or Fresnel. It is a proxy: a shading
/// point's actual BSDF differs by its view angle, its horizon and its axis's distance from the table's; any positive
/// weight keeps an estimator unbiased, the proxy only decides how well the samples follow the product.
///
/// Tables. The axes are binned on an octahedral grid of B x B cells (OctahedralMap's square; B = 16 for the cosine,
/// 32 for GGX lobes: a narrow lobe needs its axis closer to the table's). For every (lobe, axis bin) a
/// RefinedDistribution2D over the environment's hierarchical table: the cells are the pyramid's nodes at the level
/// whose width is nearest to 32 columns (in log2), each weighted by
///     w(cell) = sum over its 4 sub-nodes s (the level below) of node(s) x lobe(cos(max(0, angle - delta)))
///             + 0.1 x node(cell) x sum(w) / sum(node)
/// with angle the angle between the bin's centre axis and the sub-node's centre, and delta the bin's radius plus
/// the sub-node's (the largest lobe value any axis of the bin gives any direction of the sub-node, so that no
/// point's lobe is cut where its table's is 0, e.g. a bright window just above a point's horizon but below its
/// bin centre's). The second term is the floor; a cell with light weighs at least the smallest normal float.
/// Within a cell, texels are drawn in proportion to the environment (the pyramid's own sums). The floor puts
/// a share of every cell with light into the table, so pdf > 0 wherever the environment has light: unbiased with
/// or without MIS, whatever lobe or axis a shading point is given.
/// Density: every table is a SphericalDistribution over the environment's grid (the same sample() / pdf() /
/// texel_pdf() as the baked tables), sharing the grid's geometry.
/// Thread-safe and immutable after construction; built with oneTBB (results do not depend on the thread count).
#include <envkit/sampling/env_sampling.h>

#include <memory>
#include <vector>

namespace envkit {

class HierarchicalDistribution2D;

/// A lobe shape (see the file comment).
struct Lobe {
  enum class Shape { Cosine, Ggx };
  Shape shape = Shape::Cosine;
  double alpha = 1.0;  ///< GGX roughness (Ggx only), in [1e-3, 1]
  /// The lobe's value at cosine c between a direction and its axis (>= 0, finite).
  double value(double c) const;
  /// Same shape, and for GGX the same alpha.
  bool operator==(const Lobe& other) const {
    return shape == other.shape && (shape == Shape::Cosine || alpha == other.alpha);
  }
};

class LobeProductTables {
 public:
  /// env: a hierarchical (pyramid) table (Error otherwise); lobes: at least one, GGX alphas in [1e-3, 1].
  LobeProductTables(const SphericalDistribution& env, std::vector<Lobe> lobes);

  /// One product table and what its lobe sees.
  struct Table {
    const SphericalDistribution& distribution;
    /// The environment's importance averaged over the table's lobe (the lobe as its weights use it, widened over
    /// the bin): sum of importance x solid angle x lobe over sum of solid angle x lobe, in the hierarchical table's
    /// units. Comparable between the tables of one LobeProductTables: how bright the sky a lobe at that axis sees is.
    double mean_importance;
  };
  /// The table for lobe `lobe` (index into lobes(); Error outside) whose axis bin holds `axis` (table frame, any
  /// length > 0; a zero or NaN axis gets bin 0).
  Table table(int lobe, const Vec3& axis) const;
  const std::vector<Lobe>& lobes() const { return lobes_; }
  /// Index of lobe in lobes(), or -1 (the cosine lobe's alpha is not compared).
  int find(const Lobe& lobe) const;
  std::size_t bytes() const;

 private:
  std::vector<Lobe> lobes_;
  std::vector<int> bins_;                      // B per lobe
  std::vector<std::size_t> first_;             // index of each lobe's first table
  std::vector<SphericalDistribution> tables_;  // per lobe, B x B axis bins, row-major
  std::vector<double> mean_;                   // Table::mean_importance per table
  std::size_t table_index(int lobe, const Vec3& axis) const;
};

}  // namespace envkit
