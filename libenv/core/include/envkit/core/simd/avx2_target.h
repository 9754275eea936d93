#pragma once
// Internal to libenv (its vector kernels).
// For the files whose functions are compiled for AVX2 alone and called only when use_avx2() (simd_level.h): the
// intrinsics and the attribute that marks those functions.
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ENVKIT_AVX2 __attribute__((target("avx2")))
#endif
