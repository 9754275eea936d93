#include <envkit/huge_page_allocator.h>

#include <sys/mman.h>

#include <cstdlib>

namespace envkit::detail {

namespace {
constexpr std::size_t kHugePage = std::size_t(2) << 20;
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
