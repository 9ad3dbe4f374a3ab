// An allocator for large arrays of plain data that are filled right after they are sized.
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace qtmv {

/// std::allocator, but resize() leaves new elements of a trivial type uninitialised: arrays
/// that are filled at once after they are sized (outline cells copied from a GPU, a batch of
/// sites copied on all threads) are then first touched by the threads that fill them, instead of
/// being zeroed first on one thread, which took longer than the copies.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() noexcept = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A vector whose resize() leaves new elements of a trivial type uninitialised (see above).
template <class T>
using DefaultInitVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace qtmv
