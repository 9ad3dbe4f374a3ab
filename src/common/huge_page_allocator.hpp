// An allocator for arrays of gigabytes filled on all cores: their memory in transparent huge pages.
#pragma once

#include <cstddef>
#include <memory>
#include <new>

#include "common/default_init_allocator.hpp"

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace qtmv {

/// Arrays from this size (bytes) on get a mapping of their own in huge pages (two of them: an
/// array of millions of sites' sums, read and added to anywhere, misses the TLB in small pages).
constexpr std::size_t kHugePageArrayBytes = std::size_t{4} << 20;

/// DefaultInitAllocator (resize leaves trivial elements uninitialised), but an array of
/// kHugePageArrayBytes or more is a mapping of its own for which the kernel is asked for
/// transparent huge pages (madvise MADV_HUGEPAGE; "madvise" is Linux's usual THP mode): one
/// 2 MiB page is faulted in, and given back, where 512 small ones were. The page faults of 16
/// threads filling gigabytes of region edges otherwise wait on each other. Elsewhere, or where
/// the advice is refused, the memory is what std::allocator or mmap gives.
template <class T>
struct HugePageAllocator : DefaultInitAllocator<T> {
  template <class U>
  struct rebind {
    using other = HugePageAllocator<U>;
  };
  HugePageAllocator() noexcept = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (n * sizeof(T) >= kHugePageArrayBytes) {
      void* p = ::mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      (void)::madvise(p, n * sizeof(T), MADV_HUGEPAGE);  // advice only: refused, small pages
      return static_cast<T*>(p);
    }
#endif
    return std::allocator<T>().allocate(n);
  }
  void deallocate(T* p, std::size_t n) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (n * sizeof(T) >= kHugePageArrayBytes) {
      (void)::munmap(p, n * sizeof(T));
      return;
    }
#endif
    std::allocator<T>().deallocate(p, n);
  }
};

template <class T, class U>
bool operator==(const HugePageAllocator<T>&, const HugePageAllocator<U>&) noexcept {
  return true;
}
template <class T, class U>
bool operator!=(const HugePageAllocator<T>&, const HugePageAllocator<U>&) noexcept {
  return false;
}

}  // namespace qtmv
