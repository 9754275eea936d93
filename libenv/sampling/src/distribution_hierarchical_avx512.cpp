// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from pick().
#include <cstdint>

#include "distribution_hierarchical_simd.h"
// Last: its pragma holds for the rest of the file.
#include <envkit/core/simd/lanes_avx512.h>

namespace envkit::detail {

#if defined(ENVKIT_AVX512)

namespace {

using Lanes = Avx512Lanes;

#define ENVKIT_LANES_TARGET ENVKIT_AVX512
#include "distribution_hierarchical_descent.inl"
#undef ENVKIT_LANES_TARGET

}  // namespace

ENVKIT_AVX512 void hierarchical_pick_group_avx512(const HierarchicalWalk& w, const Vec2* u, TexelSample* out,
                                                  std::size_t n) {
  descend(w, u, out, n);
}

#else

void hierarchical_pick_group_avx512(const HierarchicalWalk&, const Vec2*, TexelSample*, std::size_t) {}

#endif

}  // namespace envkit::detail
