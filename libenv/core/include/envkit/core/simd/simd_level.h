#pragma once
// Internal to libenv (its vector kernels).
// Which vector code paths this process uses: the best the CPU has, unless ENVKIT_SIMD caps it: "none" for the portable
// paths only, "avx2" for AVX2 even on an AVX-512 CPU (to rule a path out when chasing a problem, and for the tests that
// hold every path to the portable one bit for bit).
namespace envkit::detail {

/// True when the CPU has AVX-512 F and DQ and ENVKIT_SIMD does not cap the level below it. Read once per process.
bool use_avx512();
/// True when the CPU has AVX2 and ENVKIT_SIMD is not "none" (also true where use_avx512() is). Read once per process.
bool use_avx2();

}  // namespace envkit::detail
