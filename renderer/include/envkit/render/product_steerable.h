#pragma once
/// @file product_steerable.h
/// Steerable importance sampling of BSDF x cos x environment, after Subr and Arvo, "Steerable Importance Sampling",
/// IEEE Symposium on Interactive Ray Tracing 2007, pp. 133-140: the strategies product-steerable and
/// product-steerable-mis (integrator.h).
///
/// The paper steers the environment's importance by a function of the shading point's orientation written in a
/// steerable basis, spherical harmonics, whose per-triangle weights accumulate over any group of triangles: one
/// table of the lighting per basis function, combined at the point by its coefficients, and sampled in O(log n)
/// down a hierarchy. The paper's steering function is the clamped cosine; here it is every material's BSDF x cos,
/// fitted per outgoing elevation as two zonal lobes (basis_hierarchy.h, BsdfLobeFit), so that glossy, plastic and
/// measured materials steer too. Its basis is sh.h's real SH up to band `order` (K = (order + 1)^2 functions), and
/// the paper's triangulated height field is the quadtree of the sphere's equal-area square (basis_hierarchy.h).
///
/// Precomputation, once per map: for every basis function Y_k and every finest cell of R x R, the lighting's
/// importance (the hierarchical table's weights: luminance x solid angle; every pyramid node at ~8 R columns falls
/// into the cell holding its centre) times Y_k at the node's centre, summed: T_k(cell) ~ integral over the cell of
/// L Y_k; coarser levels are sums of their children. Per material: BsdfLobeFit (order, wo_bins).
/// A shading point: the fitted BSDF x cos rotated into the tables' frame (its SH coefficients c, zonal rotation
/// formula), a cell's mass c . T(cell) ~ the integral of BSDF x cos x L over the cell, clamped at 0 and sampled by
/// hierarchical warping (uniform inside a finest cell), mixed with a defensive share of the plain table
/// (BasisProductPoint): the returned pdf is that mixture's, exact.
/// The resolution limit: inside a finest cell (4 pi / R^2 sr, 3.2 degrees across at R = 64) directions are uniform, so
/// a light much smaller than a cell (a sun) is drawn with its cell's probability spread over the cell, and is found
/// exactly only by the defensive share. A larger R narrows the cells (two more levels per factor of 4 in memory).
///
/// Cost, defaults (order 8: K 81, R 64, 32 wo bins): memory K x (4 R^2 - 1) / 3 floats = 1.7 MiB per map and
/// 2 (order + 1) x wo_bins doubles per material (4.6 KiB); precomputation K per pyramid node (0.13 M nodes at
/// 512 columns) and 2 x 32^2 eval()s per wo bin and material; per shading point two SH evaluations; per sample and
/// per pdf 4 K multiply-adds per quadtree level (6 levels) and one lookup of the plain table.
#include <envkit/render/basis_hierarchy.h>
#include <envkit/render/material.h>
#include <envkit/sampling/env_sampling.h>

#include <vector>

namespace envkit::render {

class ProductSteerable {
 public:
  /// env: the environment's hierarchical table (Error otherwise), also the defensive part of every point's mixture
  /// (kept by reference); materials: the scene's (pure delta ones get no fit). Throws Error for options out of range.
  ProductSteerable(const SphericalDistribution& env, const std::vector<const Material*>& materials,
                   const BasisProductOptions& options);

  /// A shading point's distribution: normal and wo (towards the viewer) unit, in the tables' frame.
  BasisProductPoint at(const Vec3& normal, const Vec3& wo, const Material& material) const;

  const BasisProductOptions& options() const { return options_; }
  const BasisHierarchy& hierarchy() const { return tables_; }
  /// Memory of the per-basis tables and the fits (bytes).
  std::size_t bytes() const { return tables_.bytes() + fit_.bytes(); }

 private:
  BasisProductOptions options_;
  const SphericalDistribution* env_;
  BasisHierarchy tables_;
  BsdfLobeFit fit_;
};

}  // namespace envkit::render
