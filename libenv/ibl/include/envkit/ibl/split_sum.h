#pragma once
/// @file split_sum.h
/// Split-sum specular image-based lighting evaluated from envprefilter's outputs the way a real-time shader does
/// (Karis 2013): the prefiltered radiance at the reflection direction r = 2 (n.v) n - v, read at the mip level of
/// the surface's roughness, times F0 A + B from the DFG LUT (dfg.h, scale-bias layout):
///
///   L_spec(n, v) = L_lod(roughness)(r) (F0 A(n.v, roughness) + B(n.v, roughness)).
///
/// Lookups follow the GPU's filtering: bilinear within a cube level (taps across a face edge re-projected onto the
/// neighbouring face, as seamless cube filtering does), linear between the two levels around a fractional lod
/// (trilinear), bilinear in the LUT with texel centres at (i + 0.5) / W and clamping at its edges. The lod of a
/// roughness is linear between the two levels whose roughness (the file's envkit:ibl_roughness) brackets it.
/// The viewer (web/) implements the same formulas; tests/tools/test_viewer.cpp compares the two.
#include <envkit/core/image.h>
#include <envkit/core/vec.h>

#include <memory>
#include <vector>

namespace envkit {

class CubeMap;
class TexelSource;

class SplitSumIbl {
 public:
  /// `cube_levels[m]`: level m of the GGX chain, a vertical strip of six N_m x N_m faces in the GL basis,
  /// centre-sampled (what prefilter_ggx and read_ktx2 return), at least 3 channels (RGB used).
  /// `level_roughness[m]`: perceptual roughness of level m (non-decreasing). `lut`: the DFG LUT, R = A, G = B.
  /// Throws Error when the sizes do not match.
  SplitSumIbl(std::vector<Image> cube_levels, std::vector<double> level_roughness, Image lut);
  ~SplitSumIbl();
  SplitSumIbl(const SplitSumIbl&) = delete;
  SplitSumIbl& operator=(const SplitSumIbl&) = delete;

  /// Fractional mip level of perceptual roughness r, in [0, levels - 1].
  double lod(double roughness) const;
  /// Radiance (RGB, the chain's units) in world direction `dir` (any length > 0) at fractional level `lod`.
  Vec3 radiance(const Vec3& dir, double lod) const;
  /// A and B of the LUT at (n.v, roughness), bilinear.
  void dfg(double n_dot_v, double roughness, double& a, double& b) const;
  /// The split-sum specular radiance leaving a surface with unit normal n towards unit direction v (both world
  /// frame), perceptual roughness in [0, 1] and specular colour f0 (per channel).
  Vec3 specular(const Vec3& n, const Vec3& v, double roughness, const Vec3& f0) const;

  int levels() const { return int(levels_.size()); }

 private:
  std::vector<Image> levels_;
  std::vector<std::unique_ptr<CubeMap>> params_;       // one per level
  std::vector<std::unique_ptr<TexelSource>> sources_;  // bilinear taps of each level
  std::vector<double> roughness_;
  Image lut_;
};

}  // namespace envkit
