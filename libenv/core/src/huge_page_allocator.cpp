#include <envkit/core/huge_page_allocator.h>
#include <sys/mman.h>
#include <tbb/parallel_for.h>

#include <cstdlib>
#include <cstring>

namespace envkit::detail {

namespace {
constexpr std::size_t kHugePage = std::size_t(2) << 20;
// Blocks from this size on are first touched by all cores at allocation.
constexpr std::size_t kParallelTouch = std::size_t(32) << 20;
std::size_t round_up(std::size_t bytes) { return (bytes + kHugePage - 1) / kHugePage * kHugePage; }
}  // namespace

void* allocate_huge(std::size_t bytes) {
  if (bytes < kHugePageThreshold) return ::operator new(bytes);
  const std::size_t rounded = round_up(bytes);
  if (rounded < bytes) throw std::bad_alloc();
  void* p = std::aligned_alloc(kHugePage, rounded);
  if (!p) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
  madvise(p, rounded, MADV_HUGEPAGE);  // a hint: failure (THP disabled) leaves ordinary pages
#endif
  // On a virtual machine the first touch of a page the host has taken back costs a host fault (BENCHMARKS.md,
  // section 0): taken here by every core side by side, not by the one thread that later fills the block.
  if (rounded >= kParallelTouch)
    tbb::parallel_for(std::size_t(0), rounded / kHugePage,
                      [p](std::size_t c) { std::memset(static_cast<char*>(p) + c * kHugePage, 0, kHugePage); });
  return p;
}

void deallocate_huge(void* p, std::size_t bytes) noexcept {
  if (bytes < kHugePageThreshold) {
    ::operator delete(p);
    return;
  }
  std::free(p);
}

}  // namespace envkit::detail
