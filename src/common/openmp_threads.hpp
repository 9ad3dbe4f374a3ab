// The CPU threads a run uses (OpenMP), one rule for every stage: the readers', the labeller's and
// the writers'. A run's -threads sets the default (ScopedDefaultThreads), so that every parallel
// region, sort and pool of the run stays within it, not only those given the count.
#pragma once

#include <atomic>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace qtmv {

namespace detail {
/// The default that thread_count(0) gives; 0: OpenMP's.
inline std::atomic<int> default_threads{0};
}  // namespace detail

/// `requested` threads; when 0, the default set by ScopedDefaultThreads, else OpenMP's default
/// (1 without OpenMP).
inline int thread_count(int requested) {
#ifdef _OPENMP
  if (requested > 0) return requested;
  const int set = detail::default_threads.load(std::memory_order_relaxed);
  return set > 0 ? set : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

/// Sets the process's default thread count (thread_count(0)) for its lifetime and restores the
/// one before; `threads` 0 leaves it as it is. One run at a time per process: two runs with
/// different counts at once would share the later one's.
class ScopedDefaultThreads {
 public:
  explicit ScopedDefaultThreads(int threads) : before_(detail::default_threads.load()) {
    if (threads > 0) detail::default_threads.store(threads);
  }
  ~ScopedDefaultThreads() { detail::default_threads.store(before_); }
  ScopedDefaultThreads(const ScopedDefaultThreads&) = delete;
  ScopedDefaultThreads& operator=(const ScopedDefaultThreads&) = delete;

 private:
  int before_;
};

/// The calling thread's number in the current parallel region (0 outside one).
inline int thread_index() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

/// The number of threads in the current parallel region (1 outside one).
inline int team_size() {
#ifdef _OPENMP
  return omp_get_num_threads();
#else
  return 1;
#endif
}

}  // namespace qtmv
