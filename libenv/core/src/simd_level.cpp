#include <envkit/core/simd/simd_level.h>

#include <cstdlib>
#include <cstring>

namespace envkit::detail {
namespace {

enum Level { kPortable = 0, kAvx2 = 1, kAvx512 = 2 };

Level level() {
  static const Level chosen = [] {
#if defined(__x86_64__) && defined(__GNUC__)
    __builtin_cpu_init();
    Level best = kPortable;
    if (__builtin_cpu_supports("avx2")) best = kAvx2;
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")) best = kAvx512;
    const char* wanted = std::getenv("ENVKIT_SIMD");
    if (wanted && std::strcmp(wanted, "none") == 0) return kPortable;
    if (wanted && std::strcmp(wanted, "avx2") == 0 && best > kAvx2) return kAvx2;
    return best;
#else
    return kPortable;
#endif
  }();
  return chosen;
}

}  // namespace

bool use_avx512() { return level() == kAvx512; }
bool use_avx2() { return level() >= kAvx2; }

}  // namespace envkit::detail
