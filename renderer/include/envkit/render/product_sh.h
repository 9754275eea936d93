#pragma once
/// @file product_sh.h
/// Spherical-harmonics product sampling of BSDF x cos x environment, after Jarosz, Carr and Jensen, "Importance
/// Sampling Spherical Harmonics", Computer Graphics Forum 28(2) (Eurographics 2009): the strategies product-sh and
/// product-sh-mis (integrator.h).
///
/// The paper samples a function given by its SH coefficients by hierarchical sample warping over a spherical
/// mip-map of the function's integrals, each node's integral being the coefficients dotted with the node's
/// precomputed integrals of the basis functions, and applies it to a BRDF in SH rotated on the fly. Here the
/// function is the SH product of the lighting and the shading point's BSDF x cos:
///  - lighting: the environment's importance (the hierarchical table's weights, luminance x solid angle, pyramid
///    nodes at ~8 R columns) projected once onto sh.h's real SH up to band `order`: lambda_i;
///  - BSDF x cos: every material's fit as two zonal lobes (basis_hierarchy.h, BsdfLobeFit), rotated into the tables'
///    frame by the zonal rotation formula c_lm = sqrt(4 pi / (2l + 1)) z_l Y_lm(axis): c_j;
///  - product: P_k = sum_ij C_kij lambda_i c_j, C the SH triple-product (Gaunt) coefficients, truncated to band
///    `order`. The lighting is fixed, so its contraction with C, the product matrix M_kj = integral of Y_k Y_j
///    lambda, is built once by a quadrature exact for the degree 3 x order integrand (Gauss-Legendre in z x
///    equispaced longitudes); a point costs M c, K^2 multiply-adds (K = (order + 1)^2);
///  - sampling: the mip-map of the integrals of every Y_k over the cells of the sphere's equal-area square
///    (basis_hierarchy.h; 4 x 4 points per finest cell), P dotted with them, clamped at 0, warped down the quadtree,
///    mixed with a defensive share of the plain table (BasisProductPoint); the returned pdf is exact.
/// The lighting is band-limited to `order`: a sun becomes a lobe some 180 / order degrees wide, and the defensive
/// share of the plain table is what finds it exactly (the paper's resolution limit).
///
/// Cost, defaults (order 8: K 81, R 64, 32 wo bins): memory K x (4 R^2 - 1) / 3 floats (1.7 MiB, independent of
/// the map) + K^2 doubles (51 KiB) per map + the fits; precomputation R^2 x 16 SH evaluations, K per pyramid node
/// and (3 order / 2 + 2) x (3 order + 2) x K^2 for M; per shading point two SH evaluations and K^2 multiply-adds;
/// per sample and per pdf 4 K multiply-adds per quadtree level and one lookup of the plain table.
#include <envkit/render/basis_hierarchy.h>
#include <envkit/render/material.h>
#include <envkit/sampling/env_sampling.h>

#include <vector>

namespace envkit::render {

class ProductSh {
 public:
  /// env: the environment's hierarchical table (Error otherwise), also the defensive part of every point's mixture
  /// (kept by reference); materials: the scene's (pure delta ones get no fit). Throws Error for options out of range.
  ProductSh(const SphericalDistribution& env, const std::vector<const Material*>& materials,
            const BasisProductOptions& options);

  /// A shading point's distribution: normal and wo (towards the viewer) unit, in the tables' frame.
  BasisProductPoint at(const Vec3& normal, const Vec3& wo, const Material& material) const;

  const BasisProductOptions& options() const { return options_; }
  const BasisHierarchy& hierarchy() const { return cells_; }
  /// The lighting's SH coefficients (importance, tables' frame) and the product matrix M (K x K, row k).
  const std::vector<double>& lighting() const { return lighting_; }
  const std::vector<double>& product_matrix() const { return matrix_; }
  /// Memory of the cell integrals, the matrix and the fits (bytes).
  std::size_t bytes() const {
    return cells_.bytes() + (matrix_.size() + lighting_.size()) * sizeof(double) + fit_.bytes();
  }

 private:
  BasisProductOptions options_;
  const SphericalDistribution* env_;
  BasisHierarchy cells_;
  std::vector<double> lighting_, matrix_;
  BsdfLobeFit fit_;
};

}  // namespace envkit::render
