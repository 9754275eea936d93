#pragma once
/// @file prefilter.h
/// GGX radiance prefiltering for real-time image-based lighting (the split-sum
/// approximation, Karis 2013).
///
/// Level m of the chain holds, at each texel direction r (world frame, unit),
///
///   L_m(r) = sum_s L_s D(n.h_s) (n.l_s) Omega_s / sum_s D(n.h_s) (n.l_s)
///   Omega_s,   n = v = r,
///
/// the average of the source radiance under the GGX normal distribution D with
/// alpha_m (Trowbridge-Reitz, D(c) = alpha^2 / (pi ((alpha^2 - 1) c^2 + 1)^2)),
/// weighted by the cosine n.l over the hemisphere around r, with h = (r + l) /
/// |r + l|, so n.h = sqrt((1 + r.l) / 2). Level 0 is the map area-resampled
/// (resample.h, Filter::Area) to the output: a mirror. The weights depend only
/// on the angle between r and l, so the normalisation makes a constant map
/// exactly constant at every level.
///
/// Method (deterministic quadrature, no random samples, hence no fireflies):
/// the source texels are gathered into a cube of `source_size` (a power of two)
/// by the cube texel that holds their centre, with their exact flux (L x exact
/// texel solid angle), solid angle and centroids, and summed into a cube
/// tree (each coarser texel holds the flux and solid angle of its four
/// children): a hierarchy over the source texels themselves. Each output texel
/// walks that tree from the six 1x1 faces down, refining a texel into its
/// children while its angular radius exceeds `accuracy` t (t / 2 alpha)^(1/6),
/// t = its distance to r + 2 alpha (the slow growth lets far nodes, which hold
/// little of the lobe's weight, be relatively larger): near the lobe's peak it
/// reads fine texels, in the lobe's long
/// tails coarser and coarser ones, and the whole hemisphere is always covered
/// (the tails of GGX are never cut off); texels across r's horizon refine
/// while larger than 0.25 accuracy / alpha. Each node keeps the flux- and
/// solid-angle-weighted means and central second moments (covariances) of its
/// directions, so that Var(c) = r^T C r carries no cancellation; a visited
/// node contributes w(E c) + w''(E c) Var(c) / 2 (c = r.l, second-order exact
/// over the node) times its flux, and the same rule with the solid-angle moments
/// to the normalisation. Where the summed cube is coarser than the sharpest
/// lobe needs (its memory is capped by the source's: PrefilterOptions::
/// source_size), its finest nodes keep the list of their source texels and
/// refine into them, each a point at its own direction as in the brute-force
/// sum, so a single hot texel (a sun) lands at its own direction at every
/// level. `accuracy` is the speed/accuracy knob (see docs/PREFILTER.md for
/// measured errors).
///
/// Roughness mappings (perceptual roughness r_m of level m of M, alpha = r_m^2
/// in all three):
///   Gltf     r_m = m / (M - 1) (glTF-Sample-Viewer's IBL sampler).
///   Filament r_m = 1 - sqrt(1 - m / (M - 1)) (cmgen / Filament's IBL
///            prefilter: the inverse of lod = r (2 - r), its quadratic fit of
///            log2(r) + max level).
///   Unreal   r_m = min(1, 2^((1 - (M - 1 - m)) / 1.2)) (UE's
///   ComputeReflectionCaptureRoughnessFromMip with
///            REFLECTION_CAPTURE_ROUGHEST_MIP 1, ROUGHNESS_MIP_SCALE 1.2);
///            level 0 stays the mirror image.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/parameterization.h>
#include <envkit/resample/resample.h>

#include <string>
#include <vector>

namespace envkit {

enum class RoughnessMapping { Gltf, Filament, Unreal };
/// "gltf", "filament", "unreal".
std::string roughness_mapping_name(RoughnessMapping mapping);
/// Inverse of roughness_mapping_name (also "khronos", "ue4", "ue"). Throws
/// Error.
RoughnessMapping parse_roughness_mapping(const std::string& name);
/// Perceptual roughness of level `level` of a chain of `levels` levels (levels
/// >= 1; 0 for a single level).
double level_roughness(RoughnessMapping mapping, int level, int levels);

/// GGX normal distribution D(n.h) for alpha > 0 (per steradian of half-vector
/// directions).
double ggx_d(double n_dot_h, double alpha);

struct PrefilterOptions {
  /// Output parameterization: Kind::CubeMap (vertical strip, faces per
  /// cube_basis and cube_grid) or Kind::Octahedral.
  Kind kind = Kind::CubeMap;
  /// Cube faces: the GL/KTX face table, centre-sampled (default), or OpenEXR's
  /// own cube (CubeBasis::Envkit with TexelGrid::Corner, what exr_cube_mips.h
  /// writes). The quadrature evaluates each output texel at its own direction,
  /// so either grid is exact.
  CubeBasis cube_basis = CubeBasis::GL;
  TexelGrid cube_grid = TexelGrid::Centre;
  /// Level 0 face size (cube) or side (octahedral), >= 1. Level m has size
  /// max(1, size >> m).
  int size = 256;
  /// Number of levels; 0 = the full chain down to 1 x 1 (log2(size) + 1).
  int levels = 0;
  RoughnessMapping mapping = RoughnessMapping::Gltf;
  /// Output map frame -> world (the convention the output is written for;
  /// identity = envkit's and GL's frame).
  Mat3 to_world = identity3();
  /// Refinement threshold (radians per radian): smaller is slower (cost ~ 1 /
  /// accuracy^2) and more exact. 0.2 keeps every level of chains of 8^2 to
  /// 256^2 within 0.5% relative RMS of the brute-force sum, on smooth maps,
  /// textured ones and a sun (docs/PREFILTER.md has the table per accuracy).
  double accuracy = 0.2;
  /// Face size of the summed source cube (a power of two, at most 16384); 0 =
  /// the first whose texel radius is within accuracy x 2 alpha of the sharpest
  /// level and within 0.25 accuracy / alpha of the roughest (the walk never
  /// refines finer nodes), but no finer than the largest cube whose tree
  /// (about 230 bytes per finest node while gathering) takes at most 4 times
  /// the source image's own bytes (float x channels per texel), which also
  /// keeps it coarser than the source. The output size plays no part. Finest
  /// nodes wider than the walk needs (a cube coarser than the lobe, by this cap
  /// or asked for here) refine into their source texels: exact at any cube
  /// size, a coarser cube costing walk time on the sharpest levels only.
  int source_size = 0;
  ProgressFn progress;
};

/// One prefiltered chain: levels[m] is a map (cube: vertical strip, GL basis)
/// of size max(1, size >> m).
struct PrefilteredChain {
  std::vector<EnvMap> levels;
  std::vector<double> roughness;  ///< perceptual roughness per level
  std::vector<double> alpha;      ///< GGX alpha = roughness^2 per level (level 0 is
                                  ///< filtered as alpha 0)
  RoughnessMapping mapping = RoughnessMapping::Gltf;
  int source_size = 0;                      ///< face size of the summed source cube actually used
  CubeBasis cube_basis = CubeBasis::GL;     ///< faces of a cube chain (PrefilterOptions::cube_basis)
  TexelGrid cube_grid = TexelGrid::Centre;  ///< grid of a cube chain (PrefilterOptions::cube_grid)
};

/// The output parameterization of one level (cube: vertical strip, GL basis,
/// centre-sampled unless other faces are asked for).
std::unique_ptr<Parameterization> prefilter_level_param(Kind kind, int size, CubeBasis basis = CubeBasis::GL,
                                                        TexelGrid grid = TexelGrid::Centre);

/// Prefilters `src` into a GGX chain. The output keeps the source's channels
/// (alpha, if any, is filtered as coverage like the colours). Metadata of every
/// level: envkit:ibl_roughness_mapping, envkit:ibl_level, envkit:ibl_roughness,
/// envkit:ibl_alpha. Throws Error for a size < 1, levels beyond the full chain,
/// an unsupported kind or accuracy <= 0. Parallel (oneTBB); results do not
/// depend on the thread count.
PrefilteredChain prefilter_ggx(const MapRef& src, const PrefilterOptions& options = {});

struct IrradianceOptions {
  Kind kind = Kind::CubeMap;  ///< cube (GL faces, vertical strip) or octahedral
  int size = 32;
  Mat3 to_world = identity3();
  double accuracy = 0.2;  ///< as PrefilterOptions::accuracy
  int source_size = 0;    ///< 0: the smallest power of two >= max(size, 32)
  /// true: E / pi (the radiance a white Lambertian surface reflects; what
  /// engines multiply by the albedo); false: the irradiance E itself.
  bool divide_by_pi = true;
};

/// Diffuse irradiance map by exact convolution with the clamped cosine, E(n) =
/// sum_s L_s max(0, n.l_s) Omega_s, evaluated by the same hierarchical
/// quadrature as the GGX levels (alpha = 1 makes D (n.l) the cosine / pi).
/// Metadata envkit:ibl_irradiance = "E/pi" or "E".
EnvMap irradiance_map(const MapRef& src, const IrradianceOptions& options = {});

/// The brute-force reference: the formula above at direction r (world frame),
/// summing every texel of a map times its exact solid angle (slow, O(texels)
/// per direction: for tests and measurements).
class GgxReference {
 public:
  /// Keeps a reference to src.image, which must outlive this object.
  explicit GgxReference(const MapRef& src);
  /// Writes image.channels values to out; alpha 0 means a mirror (the nearest
  /// texel's value).
  void eval(const Vec3& r, double alpha, double* out) const;

 private:
  const Image& image_;
  std::vector<Vec3> dirs_;     // world direction of each texel centre
  std::vector<double> omega_;  // exact solid angle of each texel (0 without data)
};

}  // namespace envkit
