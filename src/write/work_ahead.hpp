// Working ahead of writing: the next block of items prepared on a helper thread while this
// thread writes the block before (the vector layers' regions and Voronoi edges).
#pragma once

#include <algorithm>
#include <cstddef>
#include <future>

namespace qtmv::write {

/// Runs work(first, last), which returns the results of items first .. last - 1 (regions traced,
/// pairs' lines linked and measured: in parallel with OpenMP), on a helper thread one block ahead
/// of write(first, last, results) on this thread: OGR writes one feature at a time, so working on
/// the next block overlaps writing this one, and no more than two blocks are held. An exception
/// from either side comes out of here (after the helper has finished its block).
template <class Work, class Write>
void work_ahead(std::size_t count, std::size_t block, const Work& work, const Write& write) {
  using Results = decltype(work(std::size_t{0}, std::size_t{0}));
  const auto ahead = [&](std::size_t first) {
    return std::async(std::launch::async, [&work, first, last = std::min(count, first + block)] {
      return work(first, last);
    });
  };
  std::future<Results> next;
  if (count > 0) next = ahead(0);
  for (std::size_t first = 0; first < count; first += block) {
    const Results results = next.get();
    if (first + block < count) next = ahead(first + block);
    write(first, std::min(count, first + block), results);
  }
}

}  // namespace qtmv::write
