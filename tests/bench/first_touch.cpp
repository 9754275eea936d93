// first_touch: what first-touching fresh memory costs on this machine, with 4 KiB pages and with the 2 MiB huge
// pages envkit asks for (huge_page_allocator.h). A plain program (not Google Benchmark): the cost depends on the
// history of the process and of the machine, not on repetition.
//
//   first_touch [MiB] [repeats]     default 400 MiB (one 8192x4096 RGB float image), 3 repeats
//
// Each repeat allocates MiB, writes every byte once and frees it, first with std::malloc (4 KiB pages unless the
// kernel's THP mode is "always"), then with envkit::HugePageAllocator. On virtual machines a page that the guest
// has handed back to the host (free page reporting) costs a host fault on its next first touch: the first repeat
// after an idle pause is slower than the next ones.
#include <envkit/core/huge_page_allocator.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

int main(int argc, char** argv) {
  const std::size_t mib = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 400;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 3;
  const std::size_t bytes = mib << 20;
  for (int r = 0; r < repeats; ++r) {
    auto t0 = std::chrono::steady_clock::now();
    auto* plain = static_cast<char*>(std::malloc(bytes));
    if (!plain) return 1;
    std::memset(plain, 1, bytes);
    const double t_plain = seconds_since(t0);
    std::free(plain);
    t0 = std::chrono::steady_clock::now();
    envkit::HugePageAllocator<char> allocator;
    char* huge = allocator.allocate(bytes);
    std::memset(huge, 1, bytes);
    const double t_huge = seconds_since(t0);
    allocator.deallocate(huge, bytes);
    std::printf("repeat %d: %zu MiB first touch: 4 KiB pages %.3f s, huge pages %.3f s\n", r + 1, mib, t_plain, t_huge);
  }
}
