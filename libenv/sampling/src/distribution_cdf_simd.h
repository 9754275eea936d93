#pragma once
// detail::TwoSidedCdf::find() of a group of searches on AVX-512 (eight per vector) and AVX2 (four): the same part
// decision, the same probes and comparisons (libstdc++'s std::upper_bound / std::partition_point) and the same step
// and fraction arithmetic, so the same bins and bits, without an unpredictable jump per probe.
#include <cstddef>
#include <cstdint>

namespace envkit::detail {

/// Search k (k < n <= sampling::kSampleGroup) finds u[k] (in [0, kOneMinusEpsilon]) in the two-sided CDF of bins[k]
/// bins split at split[k] stored at base + start[k], as find(u[k], fraction[k], step[k]) returning bin[k].
/// Call only when use_avx512() (simd_level.h).
void cdf_find_group_avx512(const float* base, const std::int64_t* start, const int* bins, const int* split,
                           const double* u, std::size_t n, int* bin, double* fraction, double* step);
/// The same, four searches per vector. Call only when use_avx2().
void cdf_find_group_avx2(const float* base, const std::int64_t* start, const int* bins, const int* split,
                         const double* u, std::size_t n, int* bin, double* fraction, double* step);

}  // namespace envkit::detail
