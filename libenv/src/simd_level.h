#pragma once
// Which vector code paths this process uses: the CPU's, unless ENVKIT_SIMD=none asks for the portable paths only
// (to rule them out when chasing a problem, and for the tests that hold the two to each other bit for bit).
namespace envkit::detail {

/// True when the CPU has AVX-512 F and DQ and ENVKIT_SIMD is not "none". Read once per process.
bool use_avx512();

}  // namespace envkit::detail
