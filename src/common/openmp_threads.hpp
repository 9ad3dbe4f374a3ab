// The CPU threads a run uses (OpenMP), one rule for every stage: the labeller's and the writers'.
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace qtmv {

/// `requested` threads, or OpenMP's default when 0 (1 without OpenMP).
inline int thread_count(int requested) {
#ifdef _OPENMP
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

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
