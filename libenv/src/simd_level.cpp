#include "simd_level.h"

#include <cstdlib>
#include <cstring>

namespace envkit::detail {

bool use_avx512() {
  static const bool enabled = [] {
#if defined(__x86_64__) && defined(__GNUC__)
    const char* wanted = std::getenv("ENVKIT_SIMD");
    if (wanted && std::strcmp(wanted, "none") == 0) return false;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq");
#else
    return false;
#endif
  }();
  return enabled;
}

}  // namespace envkit::detail
