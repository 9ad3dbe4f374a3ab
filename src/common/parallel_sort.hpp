// Sorting on the run's threads (thread_count(0)) where libstdc++'s parallel mode and OpenMP are
// there (the outline cells, the regions' and Voronoi edges' cell edges: millions of items at the
// finer levels), else std::sort. Callers sort items whose order is total (no equal keys that
// differ), so the result is the same whatever the thread count.
#pragma once

#include <algorithm>
#if defined(_OPENMP) && defined(__GLIBCXX__)
#include <parallel/algorithm>
#endif

#include "common/openmp_threads.hpp"

namespace qtmv {

template <class Iterator, class Less>
void parallel_sort(Iterator first, Iterator last, Less less) {
#if defined(_OPENMP) && defined(__GLIBCXX__)
  __gnu_parallel::sort(first, last, less, __gnu_parallel::default_parallel_tag(thread_count(0)));
#else
  std::sort(first, last, less);
#endif
}

}  // namespace qtmv
