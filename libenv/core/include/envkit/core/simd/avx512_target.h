#pragma once
// Internal to libenv (its vector kernels).
// For the files whose functions are compiled for AVX-512 (F + DQ) alone and called only when use_avx512()
// (simd_level.h): the intrinsics and the attribute that marks those functions. Include it last: its pragma holds for
// the rest of the file.
#if defined(__x86_64__) && defined(__GNUC__)
#if !defined(__clang__)
// GCC 12's AVX-512 headers start masked operations from _mm512_undefined_*(), which -Wmaybe-uninitialized reports
// wherever they are inlined (GCC bug 105593); the value is never read.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#define ENVKIT_AVX512 __attribute__((target("avx512f,avx512dq")))
#endif
