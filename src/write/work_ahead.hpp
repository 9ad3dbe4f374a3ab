// Working ahead of writing: the next block of items prepared on a helper thread while this
// thread writes the block before (every vector layer: regions traced, Voronoi edges linked and
// measured, cells' geometry encoded).
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "common/openmp_threads.hpp"

namespace qtmv::write {

/// The threads for the work done beside a writing thread (work_ahead's): one core is the
/// writer's, so that the team does not take turns with it (and spin at its barriers while the
/// writer waits for a core).
inline int ahead_threads() { return std::max(1, thread_count(0) - 1); }

/// Runs work(first, last), which returns the results of items first .. last - 1 (in parallel
/// with OpenMP, ahead_threads() of them), on a helper thread one block ahead of
/// write(first, last, results) on this thread, which may take the results by reference and move
/// from them: the dataset takes one row at a time on this thread, so working on the next block
/// overlaps writing this one, and no more than two blocks are held. An exception from either
/// side comes out of here (after the helper has finished its block).
///
/// One helper thread does every block, so that its OpenMP team is made once, not once a block
/// (a thread a core: thousands of thread starts on a large host).
template <class Work, class Write>
void work_ahead(std::size_t count, std::size_t block, const Work& work, const Write& write) {
  using Results = decltype(work(std::size_t{0}, std::size_t{0}));
  if (count == 0) return;
  std::mutex mutex;
  std::condition_variable changed;
  std::optional<Results> ready;  // the next block, done
  std::exception_ptr failure;    // the helper's
  bool stop = false;             // this thread has failed: no more blocks
  std::thread helper([&] {
    for (std::size_t first = 0; first < count; first += block) {
      {
        // The block before taken (being written) before this one is made: two blocks held.
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return stop || !ready; });
        if (stop) return;
      }
      try {
        Results results = work(first, std::min(count, first + block));
        const std::lock_guard<std::mutex> lock(mutex);
        ready.emplace(std::move(results));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        failure = std::current_exception();
      }
      changed.notify_all();
      if (failure) return;
    }
  });
  const auto halt = [&] {
    {
      const std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    changed.notify_all();
    helper.join();
  };
  try {
    for (std::size_t first = 0; first < count; first += block) {
      std::optional<Results> results;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return ready.has_value() || failure; });
        if (!ready) std::rethrow_exception(failure);
        results.swap(ready);
      }
      changed.notify_all();
      write(first, std::min(count, first + block), *results);
    }
  } catch (...) {
    halt();
    throw;
  }
  helper.join();
}

}  // namespace qtmv::write
