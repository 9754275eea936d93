#pragma once
// The pyramid's group descent on AVX-512 (eight samples per vector) and AVX2 (four): the same operations on the same
// values as HierarchicalDistribution2D::pick() (so the same bits), without its two unpredictable jumps per level.
#include <envkit/sampling/distribution.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace envkit::detail {

/// A sum pyramid as the vector descent reads it (see HierarchicalDistribution2D's Level).
struct HierarchicalWalk {
  static constexpr int kMaxLevels = 32;  // 2^24 per side gives at most 25 levels
  const float* nodes = nullptr;
  std::size_t offset[kMaxLevels] = {};          // level k's children array, in floats (a multiple of 4)
  std::size_t blocks_per_row[kMaxLevels] = {};  // blocks per row of level k's children array
  int top = 0;                                  // levels(): the descent reads levels top - 1 .. 0
  int prefetch_top = 0;                         // levels 1 .. prefetch_top prefetch the next level's block
  double pdf_scale = 0.0;
};

/// The descent's state per sample of a group, as the vector loops load and store it.
struct HierarchicalLanes {
  alignas(64) double ux[sampling::kSampleGroup], uy[sampling::kSampleGroup], leaf[sampling::kSampleGroup];
  alignas(64) std::int64_t i[sampling::kSampleGroup], j[sampling::kSampleGroup];

  /// Lanes [0, n) start from u; lanes [n, lanes) descend from u = 0 (a valid path: visited nodes have a positive sum)
  /// and are dropped by finish().
  void start(const Vec2* u, std::size_t n, std::size_t lanes) {
    for (std::size_t s = 0; s < lanes; ++s) {
      ux[s] = s < n ? sampling::clamp_decision(u[s].x) : 0.0;
      uy[s] = s < n ? sampling::clamp_decision(u[s].y) : 0.0;
      i[s] = j[s] = 0;
    }
  }
  /// The texel samples of lanes [0, n), as pick() returns them.
  void finish(const HierarchicalWalk& walk, TexelSample* out, std::size_t n) const {
    for (std::size_t s = 0; s < n; ++s) {
      out[s].fx = std::min(kTexelOffsetMax, ux[s]);
      out[s].fy = std::min(kTexelOffsetMax, uy[s]);
      out[s].pdf = leaf[s] * walk.pdf_scale;
      out[s].x = int(i[s]);
      out[s].y = int(j[s]);
    }
  }
};

/// pick(u[s]) into out[s] for s < n <= sampling::kSampleGroup. Call only when use_avx512() (simd_level.h).
void hierarchical_pick_group_avx512(const HierarchicalWalk& walk, const Vec2* u, TexelSample* out, std::size_t n);
/// The same with four samples per vector. Call only when use_avx2().
void hierarchical_pick_group_avx2(const HierarchicalWalk& walk, const Vec2* u, TexelSample* out, std::size_t n);

}  // namespace envkit::detail
