#pragma once
// The pyramid's group descent on AVX-512: eight samples per vector, the same operations on the same values as
// PyramidDistribution2D::pick() (so the same bits), without its two unpredictable branches per level.
#include <envkit/distribution.h>

#include <cstddef>

namespace envkit::detail {

/// A sum pyramid as the vector descent reads it (see PyramidDistribution2D's Level).
struct PyramidWalk {
  static constexpr int kMaxLevels = 32;  // 2^24 per side gives at most 25 levels
  const float* nodes = nullptr;
  std::size_t offset[kMaxLevels] = {};          // level k's children array, in floats (a multiple of 4)
  std::size_t blocks_per_row[kMaxLevels] = {};  // blocks per row of level k's children array
  int top = 0;                                  // levels(): the descent reads levels top - 1 .. 0
  int prefetch_top = 0;                         // levels 1 .. prefetch_top prefetch the next level's block
  double pdf_scale = 0.0;
};

/// pick(u[s]) into out[s] for s < n <= sampling::kSampleGroup. Call only when use_avx512() (simd_level.h).
void pyramid_pick_group_avx512(const PyramidWalk& walk, const Vec2* u, TexelSample* out, std::size_t n);

}  // namespace envkit::detail
