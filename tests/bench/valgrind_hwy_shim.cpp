// LD_PRELOAD shim for instruction counting under valgrind (scripts/bench/bench_bake.sh section c).
//
// The benchmark programs link OpenImageIO, which brings libjxl's libhwy; libhwy's start-up code measures its timer
// with rdtscp, an instruction valgrind 3.19 does not decode (SIGILL before main). Preloading this definition of the
// one function that executes it keeps the process alive; nothing envkit measures uses it.
#include <cstdint>

namespace hwy::platform {
std::uint64_t TimerResolution() { return 1; }  // ticks per timer increment: any positive value will do
}  // namespace hwy::platform
