#pragma once
// The moment tree over the summed cube behind GGX prefiltering and irradiance (prefilter.h states the method): a
// hierarchy over the source texels with exact flux, solid angle, and the means and central second moments of their
// directions, walked once per output direction.
#include <envkit/core/huge_page_allocator.h>
#include <envkit/core/vec.h>
#include <envkit/resample/resample.h>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace envkit::detail {

// Four float lanes; GCC/Clang vector extensions, so the same code is SSE on x86-64 and NEON or scalar elsewhere.
using Float4 = float __attribute__((vector_size(16)));
using Int4 = std::int32_t __attribute__((vector_size(16)));

// Four sibling nodes (the children of one parent; lane q = 2 dj + di) with their fields in lanes, so that the walk
// tests and sums a whole family at once. The first line is all a walk reads of a family it only refines or skips.
struct alignas(16) NodeFamily {
  Float4 omega_mean[3];  // solid-angle-weighted mean of the unit directions below (length <= 1)
  Float4 omega_gap;      // 1 - |omega_mean|^2, so that 1 - r . mean = (|r - mean|^2 + gap) / 2 keeps its digits
  Float4 flux_mean[3];   // the same, weighted by |flux|
  Float4 flux_gap;
  // Central second moments E[(d - mean)(d - mean)^T] (xx, yy, zz, xy, xz, yz): the variance of r . d is r^T C r,
  // with no difference of two numbers near 1.
  Float4 omega_cov[6];
  Float4 flux_cov[6];
  Float4 flux[4];  // exact flux per channel (radiance x exact solid angle, summed)
  Float4 omega;    // exact solid angle
};

class MomentTree {
 public:
  // Gathers `src` (world frame by src.to_world) into a cube of face_size (a power of two, at most 16384) by the
  // cube texel that holds each source texel's centre, then sums upward. With keep_texels the source texels also
  // stay listed under their finest node, so that a walk can refine a finest node into its texels (for lobes
  // narrower than the cube's texels); without, such nodes act as points at their centroids.
  MomentTree(const MapRef& src, int face_size, bool keep_texels = false);

  static constexpr int kMaxGroup = 16;
  static constexpr int kMaxFaceSize = 16384;

  // What the walk needs for one lobe (alpha > 0) and accuracy, per tree level: thresholds on e = 1 - r . mean.
  // Made once per output level (walk()), not per direction.
  struct Walk {
    double alpha = 0.0;
    // Finest nodes wider than the lobe's peak act as points at their unit centroids (only without kept texels,
    // which they refine into instead).
    bool finest_points = false;
    std::array<float, 32> skip_above{}, straddle_above{}, refine_below{};
    std::array<bool, 32> horizon_refine{};
  };
  Walk walk(double alpha, double accuracy) const;

  // The split-sum average around each unit direction of r (world frame) for the walk's lobe (prefilter.h); writes
  // channels() values per direction to out. Up to kMaxGroup directions walk the tree together, a node being
  // refined for all when one needs it: neighbouring directions share nearly all their walk, which then loads each
  // node once for the group. The values depend on the grouping only within the walk's accuracy.
  void filter(const Walk& walk, std::span<const Vec3> r, std::span<float> out) const;

  int channels() const { return channels_; }

  // Bound on the angular radius of a texel of a cube of face size `size` about its centre (radians).
  static double texel_radius(int size);

  // Bytes the tree of face size `face_size` holds at its peak (while gathering), without the texel lists.
  static double peak_bytes(int face_size);

 private:
  // One source texel under a finest node: its unit direction (world frame), flux per channel and solid angle.
  struct Texel {
    float d[3];
    float flux[4];
    float omega;
  };

  void gather(const MapRef& src, int face_size, bool keep_texels);
  void sum_upward();

  int channels_;
  int alpha_channel_;  // excluded from the weight of the flux means
  int finest_ = 0;     // level of the gathered cube (face size 2^finest_)
  // Level k >= 1: family n holds the children of node n of level k - 1 (node index = face * 4^k + Morton(i, j));
  // level 0: two families, the six faces and two empty lanes. Uninitialised storage: the gather and sum_upward
  // write every lane, on every core.
  std::vector<std::vector<NodeFamily, UninitialisedAllocator<NodeFamily>>> levels_;
  std::vector<double> radius_;  // texel_radius(2^k)
  // With keep_texels: the texels of finest node n (face * 4^finest + Morton(i, j)) are
  // texels_[first_texel_[n] .. first_texel_[n + 1]), in source order; both empty without.
  std::vector<std::uint32_t> first_texel_;
  std::vector<Texel> texels_;
};

}  // namespace envkit::detail
