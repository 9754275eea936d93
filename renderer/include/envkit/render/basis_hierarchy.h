#pragma once
/// @file basis_hierarchy.h
/// What the steerable (product_steerable.h) and spherical-harmonics (product_sh.h) product samplers share: a
/// function over the sphere given at a shading point by K coefficients of a basis, whose mass in every cell of a
/// quadtree is the coefficients dotted with the cell's precomputed per-basis integrals, sampled by hierarchical
/// sample warping down that quadtree; the BSDF x cos of every material fitted as two zonal lobes in real spherical
/// harmonics (sh.h's basis); and the point's distribution, that function mixed with a defensive share of the plain
/// environment table.
///
/// The sphere's square. [0,1]^2 covers the whole sphere of the tables' frame through cap_from_square(u, 2)
/// (product_wavelet.h: Shirley and Chiu's concentric map and the equal-area lift; its square's rim is the -z pole):
/// every cell of an R x R grid covers 4 pi / R^2 steradians. The quadtree's level k (0..log2 R) has 2^k x 2^k
/// nodes; a node's integrals are the sums of its four children's, the finest level's are given.
///
/// Sampling a point's coefficients c (Jarosz, Carr and Jensen 2009: hierarchical sample warping over a spherical
/// mip-map of the SH function's integrals). Below a node, each child's mass is max(c . integrals, 0): an
/// approximation can be negative (ringing), and the clamp keeps a density. The first coordinate of u picks the
/// left or right column of children in proportion to their masses and is rescaled, the second picks the child in
/// that column; at the finest level the direction is uniform in the cell. The pdf of a direction is the product of
/// the conditional choices along its cell's path x R^2 / (4 pi): exactly the density the warping draws (a
/// piecewise-constant one over the finest cells). Should the four children of a chosen node all clamp to 0 (their
/// sum is the node's positive mass up to rounding of the stored floats), each is taken with probability 1/4.
///
/// Cost. Memory: K floats per node, (4 R^2 - 1) / 3 nodes. Per sample and per pdf: 4 K multiply-adds per level.
#include <envkit/core/vec.h>
#include <envkit/render/material.h>
#include <envkit/sampling/env_sampling.h>

#include <optional>
#include <string>
#include <vector>

namespace envkit::render {

/// A node of an environment table's pyramid: its centre direction (tables' frame) and its importance x solid angle.
struct EnvNode {
  Vec3 centre;
  double energy;
};

/// The hierarchical table's pyramid nodes at the level whose width is nearest (in log2) to `columns` (only nodes
/// with energy > 0). Throws Error unless the table is hierarchical; `who` names the strategy in that message.
std::vector<EnvNode> environment_nodes(const SphericalDistribution& env, int columns, const char* who);

/// h of cap_from_square() for the whole sphere.
inline constexpr double kWholeSphere = 2.0;

/// Per-cell integrals of K basis functions over the quadtree of the sphere's square, and sampling of c . integrals.
class BasisHierarchy {
 public:
  BasisHierarchy() = default;
  /// finest: R x R cells (row-major, y then x) of K integrals each. R a power of two in 2..1024 (Error otherwise).
  BasisHierarchy(int resolution, int count, const std::vector<double>& finest);

  int resolution() const { return resolution_; }
  int count() const { return count_; }
  /// The K integrals of node (x, y) of level k (2^k x 2^k nodes).
  const float* node(int level, int x, int y) const;
  /// c . the root's integrals: the approximation's integral over the sphere (clamping aside).
  double total(const double* c) const;
  /// Whether sample() can draw from c: a positive mass below the root.
  bool can_sample(const double* c) const;
  /// A direction (tables' frame) drawn by the warping, density per steradian; x, y: its finest cell. Needs
  /// can_sample(c).
  DirectionSample sample(const double* c, Vec2 u) const;
  /// The density sample() draws at a direction (any length; 0 for a zero or NaN vector).
  double pdf(const double* c, const Vec3& direction) const;
  std::size_t bytes() const { return nodes_.size() * sizeof(float); }

 private:
  int resolution_ = 0, count_ = 0, levels_ = 0;
  std::vector<std::size_t> level_offset_;
  std::vector<float> nodes_;
  /// The four children's clamped masses of node (x, y) of level k - 1, [j * 2 + i] for child (2x + i, 2y + j).
  void children(const double* c, int level, int x, int y, double* mass) const;
};

/// The parameters of both basis product samplers.
struct BasisProductOptions {
  int order = 8;           ///< highest SH band l of the fitted BSDF x cos (and of the lighting for product-sh), 1..16
  int resolution = 64;     ///< R: finest cells per side of the sphere's square, a power of two in 2..512
  int wo_bins = 32;        ///< fitted outgoing elevations per material, 2..256
  double defensive = 0.1;  ///< share of the plain environment table in the point's mixture, in (0, 1]
};

/// A member of BasisProductOptions out of range: which, its value as text and the rule it breaks ("must be in
/// 1..16").
struct BasisOptionProblem {
  enum class Member { Order, Resolution, WoBins, Defensive } member;
  std::string value, rule;
};
/// The first member of `options` out of its range, or nullopt: every range of the struct's comments, checked here.
std::optional<BasisOptionProblem> out_of_range(const BasisProductOptions& options);

/// Throws Error naming `who` for options out of range (out_of_range()).
void check_options(const BasisProductOptions& options, const char* who);

/// The BSDF x cos (the mean of eval()'s RGB) of each material, for each of `wo_bins` outgoing elevations (bin
/// centres uniform in theta_o, linearly interpolated), fitted as the sum of two zonal lobes up to band `order`: one
/// around the normal n and one around the mirror direction r,
///     g(wi) ~ sum_l a_l P_l(n . wi) + b_l P_l(r . wi),
/// by least squares over the sphere (g is 0 below the horizon). The integrals of g against each P_l are estimated
/// with the material's own sampling and uniform hemisphere samples (balance heuristic, 32 x 32 stratified points
/// each), so a measured or any other material fits by eval(), pdf() and sample() alone; the two axes' Gram matrix
/// per band is [[1, P_l(n . r)], [P_l(n . r), 1]] x 4 pi / (2l + 1) (Funk-Hecke), regularised by kLobeFitRidge
/// on its diagonal where the axes coincide. An isotropic BSDF's fit depends on theta_o only. Rotated to a shading
/// point by the addition theorem, P_l(a . w) = 4 pi / (2l + 1) sum_m Y_lm(a) Y_lm(w): the zonal rotation formula
/// c_lm = sqrt(4 pi / (2l + 1)) z_l Y_lm(axis) with z_l = sqrt(4 pi / (2l + 1)) a_l.
/// Pure delta materials get no fit; a material without a fit has the constant function 1.
class BsdfLobeFit {
 public:
  BsdfLobeFit() = default;
  BsdfLobeFit(const std::vector<const Material*>& materials, int order, int wo_bins);
  /// The SH coefficients (sh_count(order), tables' frame) of the material's fitted BSDF x cos at a point: normal
  /// and wo (towards the viewer) unit, tables' frame.
  void coefficients(const Material& material, const Vec3& normal, const Vec3& wo, double* out) const;
  /// The fit's zonal coefficients (a_l, b_l) for a material at cos theta_o, or false without a fit.
  bool lobes(const Material& material, double cos_theta_o, std::vector<double>& a, std::vector<double>& b) const;
  std::size_t bytes() const;

 private:
  int order_ = 0, wo_bins_ = 0;
  std::vector<const Material*> materials_;
  std::vector<std::vector<double>> fits_;  // per material: wo_bins x 2 (order + 1) (a then b)
};

/// The ridge added to the fit's normalised Gram diagonal (BsdfLobeFit).
inline constexpr double kLobeFitRidge = 0.05;

/// A shading point's distribution: (1 - d) x the hierarchy's warping of its coefficients + d x the environment's
/// table, d = options.defensive (1 when the coefficients have no positive mass). The table's density is positive
/// wherever the map is bright, so the mixture's is wherever f cos L > 0 however poor the approximation: the
/// estimator stays unbiased, and its weight f cos L / pdf is at most 1/d times light sampling's.
class BasisProductPoint {
 public:
  BasisProductPoint(const BasisHierarchy& hierarchy, std::vector<double> coefficients, const SphericalDistribution& env,
                    double defensive);
  /// A direction in the tables' frame with its density per steradian (pdf 0: none drawn).
  DirectionSample sample(Vec2 u) const;
  /// Density per steradian of a direction (tables' frame, any length).
  double pdf(const Vec3& direction) const;
  const std::vector<double>& coefficients() const { return coefficients_; }
  /// The environment table's share d of the mixture.
  double defensive() const { return defensive_; }

 private:
  const BasisHierarchy* hierarchy_;
  std::vector<double> coefficients_;
  const SphericalDistribution* env_;
  double defensive_;
};

}  // namespace envkit::render
