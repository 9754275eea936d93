// Built with -ffp-contract=off (libenv/CMakeLists.txt): a fused multiply-add would round differently from find().
#include <envkit/core/simd/lanes_avx2.h>
#include <envkit/sampling/distribution.h>

#include <algorithm>

#include "distribution_cdf_simd.h"

namespace envkit::detail {

#if defined(ENVKIT_AVX2)

namespace {

using Lanes = Avx2Lanes;

#define ENVKIT_LANES_TARGET ENVKIT_AVX2
#include "distribution_cdf_search.inl"
#undef ENVKIT_LANES_TARGET

}  // namespace

ENVKIT_AVX2 void cdf_find_group_avx2(const float* base, const std::int64_t* start, const int* bins, const int* split,
                                     const double* u, std::size_t n, int* bin, double* fraction, double* step) {
  search(base, start, bins, split, u, n, bin, fraction, step);
}

#else

void cdf_find_group_avx2(const float*, const std::int64_t*, const int*, const int*, const double*, std::size_t, int*,
                         double*, double*) {}

#endif

}  // namespace envkit::detail
