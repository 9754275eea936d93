#pragma once
/// @file product_wavelet.h
/// Wavelet importance sampling of BSDF x cos x environment, after Clarberg, Jarosz, Akenine-Moeller and Jensen,
/// "Wavelet Importance Sampling: Efficiently Evaluating Products of Complex Functions", SIGGRAPH 2005 (and
/// Clarberg's M.S. thesis, "Efficient sampling of products of functions using wavelets", Lund University 2005):
/// the strategies product-wavelet and product-wavelet-mis (integrator.h).
///
/// Parameterization. The square [0,1]^2 covers a cap z >= 1 - h around a local frame's z axis through Shirley and
/// Chiu's concentric map (square -> disk) followed by the equal-area lift of the disk (z = 1 - h r^2; h = 1 is the
/// hemisphere): every cell of an R x R grid covers the same solid angle 2 pi h / R^2, and a density p_uv over the
/// square is p_uv / (2 pi h) per steradian. The paper parameterizes the local hemisphere by a square the same way
/// (h = 1); here h = 1 + sin(the normal bins' radius), slightly more than a hemisphere, for the reason below.
///
/// The two factors, each an R x R grid of cell averages on that square, Haar-transformed (haar.h) and optionally
/// compressed to the largest `kept_coefficients` detail coefficients (the paper's compression), then decoded once:
///  - lighting: for every normal bin of an octahedral B x B grid (OctahedralMap's square, in the tables' frame), in
///    the bin's fixed tangent frame (Frame::from_normal of the bin's centre), the environment's importance (the
///    baked hierarchical table's weights: luminance x solid angle) summed over each cell: every node of the
///    table's pyramid at the level nearest 8 R columns falls into the cell holding its centre, so the cell average
///    is the sum of its nodes over the cell's solid angle (the texels' energy, not point samples);
///  - BSDF x cos: for every material and every outgoing direction bin of a W x W grid on the hemisphere's square
///    (h = 1), the average of eval() (the mean of its RGB channels) over 2 x 2 stratified points per cell of the
///    cap, wo at the bin's centre. Only eval() is used, so any material works. Pure delta materials have no table:
///    delta lobes are followed by BSDF sampling in every strategy (integrator.h).
/// Each factor is normalised to mean 1 and floored at kWaveletFloor (relative to that mean), after compression:
/// the product is then positive on every cell of the cap, so pdf > 0 wherever f cos L > 0 whatever the
/// approximation (the estimator takes the map's own radiance: unbiased).
///
/// A shading point. Its normal (tables' frame) picks a lighting bin, and the point samples the bin's own frame and
/// cap: the lighting cells then lie exactly where the environment's light is (a sun keeps its cell), and the cap,
/// wider than a hemisphere by the bin's radius, holds the point's whole hemisphere (samples below the point's
/// horizon contribute 0). (Should rounding put a normal outside its bin's radius, the bin's frame is turned onto
/// the normal by the smallest rotation, whose cap holds the hemisphere too.) wo in that frame picks the BSDF
/// slice, so the BSDF factor is the one of a normal up to the bin's radius away: an approximation that costs
/// variance, never bias. The product is evaluated as all R x R cell products of the decoded factors (one multiply
/// per cell, then the sum pyramid of a HierarchicalDistribution2D): the pyramid's node sums are the wavelet
/// product's scaling coefficients, which haar::product_sums() computes in the wavelet domain (tests check the two
/// agree). That function is the paper's product in the wavelet domain; evaluating it top-down only along a
/// sample's descent would not save its cost here: the root's sum (every coefficient's product) is needed by every
/// pdf, and a point draws M samples and evaluates N pdfs from one product, while the pointwise path needs no
/// top-down reconstruction of both factors' scaling coefficients per point. Samples warp down the product's quadtree
/// (the pyramid's hierarchical warping) and are uniform inside the finest cell, so
///     pdf(wi) = product(cell) / sum of products x R^2 / (2 pi h)   per steradian.
/// pdf() of a direction (a BSDF sample, for MIS) reads the same cell.
/// The sun is not split off: the strategy samples the whole map (the paper has no split). A sun much smaller than a
/// cell (2 pi h / R^2 sr, about 5 degrees across at R = 32) is drawn with its cell's probability spread uniformly
/// over the cell: the paper's resolution limit, visible as noise on diffuse surfaces under a small bright sun.
///
/// Cost. Memory: 4 R^2 bytes per lighting bin (B^2 of them) and per BSDF slice (W^2 per non-delta material): with
/// the defaults (R 32, B 16, W 16) 1 MiB of lighting and 1 MiB per material. Precomputation (oneTBB, deterministic:
/// each bin and slice is computed alone): B^2 x (pyramid nodes at ~8 R columns) splats for the lighting (8.4 M for a
/// 1024 x 512 map) and W^2 x 4 R^2 eval() calls per material (1 M). Per shading point: R^2 multiplies and a pyramid
/// of R^2 leaves; per sample: one descent of log2 R levels.
#include <envkit/core/vec.h>
#include <envkit/render/frame.h>
#include <envkit/render/material.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/sampling/env_sampling.h>

#include <optional>
#include <string>
#include <vector>

namespace envkit::render {

/// The parameters of the wavelet product sampler (see the file comment).
struct WaveletOptions {
  int resolution = 32;        ///< R: cells per side of the hemisphere's square, a power of two in 2..256
  int normal_bins = 16;       ///< B: lighting bins per side of the octahedral grid of normals, 1..64
  int wo_bins = 16;           ///< W: BSDF slices per side of the square of outgoing directions, 1..64
  int kept_coefficients = 0;  ///< detail coefficients kept per factor (largest magnitude); 0 = all (lossless)
};

/// A member of WaveletOptions out of range: which, its value as text and the rule it breaks.
struct WaveletOptionProblem {
  enum class Member { Resolution, NormalBins, WoBins, KeptCoefficients } member;
  std::string value, rule;
};
/// The first member of `options` out of its range, or nullopt: every range of the struct's comments, checked here.
std::optional<WaveletOptionProblem> out_of_range(const WaveletOptions& options);

/// A factor's cells are at least this fraction of its mean (after compression): the product is positive on every
/// cell, so no direction where the integrand is positive has pdf 0.
inline constexpr double kWaveletFloor = 1e-3;

/// The square [0,1]^2 -> the cap z >= 1 - h of a local frame (h = 1: the upper hemisphere, h in (0, 2]):
/// Shirley-Chiu's concentric map to the unit disk, then the equal-area lift of disk radius r to z = 1 - h r^2;
/// 2 pi h steradians per unit of square area everywhere.
Vec3 cap_from_square(Vec2 u, double h);
/// The inverse of cap_from_square(); d need not be unit; outside the cap it is clamped onto its rim.
Vec2 square_from_cap(const Vec3& d, double h);

class ProductWavelet {
 public:
  /// env: the environment's hierarchical table (Error otherwise); materials: the scene's (pure delta ones get no
  /// table). Throws Error for options out of range.
  ProductWavelet(const SphericalDistribution& env, const std::vector<const Material*>& materials,
                 const WaveletOptions& options);

  /// A shading point's product distribution.
  class Point {
   public:
    /// A direction of the point's hemisphere, tables' frame, with its density per steradian; x, y: its cell of the
    /// R x R square.
    DirectionSample sample(Vec2 u) const;
    /// Density per steradian of a direction (tables' frame, any length); 0 below the point's horizon.
    double pdf(const Vec3& direction) const;
    const Frame& frame() const { return frame_; }
    /// h of the cap the point samples (cap_from_square()): its frame's z >= 1 - h.
    double cap() const { return cap_; }

   private:
    friend class ProductWavelet;
    Point(const Frame& frame, const std::vector<float>& product, int R, double cap);
    Frame frame_;
    double cap_ = 1.0;
    HierarchicalDistribution2D product_;
  };

  /// The product at a shading point: normal and wo (towards the viewer) unit, in the tables' frame. A material
  /// without a table (not among the constructor's, or pure delta) has a constant BSDF factor.
  Point at(const Vec3& normal, const Vec3& wo, const Material& material) const;

  const WaveletOptions& options() const { return options_; }
  /// h of the cap every lighting and BSDF square covers (cap_from_square()): 1 + sin(the bins' radius).
  double cap() const { return cap_; }
  /// Memory of the decoded factors (bytes).
  std::size_t bytes() const;
  /// The decoded lighting factor of the bin holding `normal` (R x R, row-major) and its frame, for tests.
  const float* lighting(const Vec3& normal, Frame* bin_frame = nullptr) const;
  /// The decoded BSDF factor of a material's slice for local wo (R x R), or nullptr without a table.
  const float* brdf(const Material& material, const Vec3& wo_local) const;

 private:
  WaveletOptions options_;
  std::size_t cells_ = 0;                   // R^2
  std::vector<Frame> bin_frames_;           // B^2 lighting bins' frames
  double bin_radius_ = 0.0;                 // the largest angle between a bin's centre and its normals
  double cap_ = 1.0;                        // h of the squares' cap: 1 + sin(bin_radius_)
  std::vector<float> lighting_;             // B^2 x R^2
  std::vector<const Material*> materials_;  // with a table
  std::vector<std::vector<float>> brdf_;    // per material: W^2 x R^2
  std::vector<float> ones_;                 // R^2 ones: the BSDF factor of a material without a table
  int bin_of(const Vec3& normal) const;
};

}  // namespace envkit::render
