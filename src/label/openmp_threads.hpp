// The CPU threads a labelling run uses (OpenMP), one rule for every stage.
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace qtmv::label {

/// `requested` threads, or OpenMP's default when 0 (1 without OpenMP).
inline int thread_count(int requested) {
#ifdef _OPENMP
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

}  // namespace qtmv::label
