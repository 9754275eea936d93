#pragma once
/// @file huge_page_allocator.h
/// An allocator for the big buffers of envkit (pixels, tables): blocks of 4 MiB and more are 2 MiB aligned and
/// marked MADV_HUGEPAGE, so the kernel backs them with transparent huge pages when it can.
///
/// Why: first touching a fresh 4 KiB page costs a page fault, and on virtual machines such as the ones envkit is
/// measured on a fault costs several microseconds: zero-filling a 400 MB buffer (one 8192x4096 RGB float image)
/// took 1.45 s with 4 KiB pages and 0.06 s with 2 MiB pages. Debian's default THP mode is "madvise", which is
/// why the hint is needed. Where THP is off the hint is ignored and the buffer is an ordinary aligned block.
/// Small blocks go to operator new as usual.
#include <cstddef>
#include <new>
#include <utility>
#include <vector>

namespace envkit {

namespace detail {
/// Bytes from which a block is 2 MiB aligned and advised as huge-page backed.
inline constexpr std::size_t kHugePageThreshold = std::size_t(4) << 20;
void* allocate_huge(std::size_t bytes);
void deallocate_huge(void* p, std::size_t bytes) noexcept;
}  // namespace detail

template <class T>
struct HugePageAllocator {
  using value_type = T;
  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    // Small blocks come from ::operator new(bytes), aligned only to the default new alignment.
    static_assert(alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__, "over-aligned types need another allocator");
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_alloc();
    return static_cast<T*>(detail::allocate_huge(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept { detail::deallocate_huge(p, n * sizeof(T)); }

  template <class U>
  bool operator==(const HugePageAllocator<U>&) const noexcept {
    return true;
  }
};

/// HugePageAllocator whose containers leave elements without initialisers uninitialised (vector(n), resize(n)):
/// value-initialisation would first-touch, and so zero, the whole block on one thread. For buffers that parallel
/// loops fill (or zero) completely before anything reads them.
template <class T>
struct UninitialisedAllocator : HugePageAllocator<T> {
  template <class U>
  struct rebind {
    using other = UninitialisedAllocator<U>;
  };
  UninitialisedAllocator() = default;
  template <class U>
  UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// Float storage of images and tables.
using FloatBuffer = std::vector<float, HugePageAllocator<float>>;

}  // namespace envkit
