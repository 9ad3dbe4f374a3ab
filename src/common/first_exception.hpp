// Exceptions inside OpenMP parallel regions: one that leaves a region terminates the process
// (std::bad_alloc from a vector's growth, a logic_error from the tracer), so each piece of work
// runs under FirstException::run, which keeps the first, and the caller rethrows it after the
// region.
#pragma once

#include <atomic>
#include <exception>
#include <mutex>

namespace qtmv {

class FirstException {
 public:
  /// Runs `work`; an exception it throws is kept (the first one only), not thrown.
  template <class Work>
  void run(Work&& work) noexcept {
    if (failed_.load(std::memory_order_relaxed)) return;  // no more work once one has failed
    try {
      work();
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!first_) first_ = std::current_exception();
      failed_ = true;
    }
  }

  /// Whether some work has thrown (for long work to stop early).
  bool failed() const { return failed_.load(std::memory_order_relaxed); }

  /// Throws the exception kept, if any (after the parallel region).
  void rethrow() const {
    if (first_) std::rethrow_exception(first_);
  }

 private:
  std::mutex mutex_;
  std::exception_ptr first_;
  std::atomic<bool> failed_{false};
};

}  // namespace qtmv
