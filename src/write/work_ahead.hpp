// Working ahead of writing: the next block of items prepared on a helper thread's team while this
// thread writes the block before, and helped by this thread whenever it has nothing to write
// (every vector layer: regions traced, Voronoi edges linked and measured, cells' geometry
// encoded).
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"

namespace qtmv::write {

/// The threads of the helper's team (work_ahead's): one core is the writing thread's, which
/// helps the team when it has nothing to write; so no core is taken in turns (and no team spins
/// at its barriers while the writer waits for a core).
inline int ahead_threads() { return std::max(1, thread_count(0) - 1); }

/// Writes `count` items in blocks of `block`, each block made ahead of its writing:
///   begin(first, last) -> std::pair<Results, std::size_t>: block [first, last)'s results,
///     sized, and how many pieces of work they take (on the helper thread);
///   item(results, k): piece k of those (k < pieces), on any thread, in any order: the helper's
///     OpenMP team (ahead_threads()) and this thread, while it waits for the block, take them
///     `grain` at a time;
///   write(first, last, results) on this thread, which may move from the results.
/// The dataset takes one row at a time on this thread, so making the next block overlaps
/// writing this one, and this thread helps make it when it is done first. No more than two
/// blocks are held. An exception from either side comes out of here (after the helper has
/// finished its block). One helper thread does every block, so that its OpenMP team is made
/// once, not once a block (a thread a core: thousands of thread starts on a large host).
template <class Begin, class Item, class Write>
void work_ahead(std::size_t count, std::size_t block, std::size_t grain, const Begin& begin, const Item& item,
                const Write& write) {
  using Results = typename decltype(begin(std::size_t{0}, std::size_t{0}))::first_type;
  if (count == 0) return;
  grain = std::max<std::size_t>(1, grain);
  // The block being made: its pieces taken from `next`, `done` once made.
  struct Making {
    Results* results;
    std::size_t pieces;
    std::atomic<std::size_t> next{0}, done{0};
    FirstException failure;
  };
  // Makes pieces of `m` until none is left; the last one done wakes the helper.
  const auto take = [&item, grain](Making& m, std::condition_variable& changed, std::mutex& mutex) {
    for (;;) {
      const std::size_t from = m.next.fetch_add(grain);
      if (from >= m.pieces) return;
      const std::size_t to = std::min(m.pieces, from + grain);
      for (std::size_t k = from; k < to; ++k) m.failure.run([&] { item(*m.results, k); });
      if (m.done.fetch_add(to - from) + (to - from) == m.pieces) {
        const std::lock_guard<std::mutex> lock(mutex);
        changed.notify_all();
      }
    }
  };
  std::mutex mutex;
  std::condition_variable changed;
  std::optional<Results> ready;     // the next block, made
  std::shared_ptr<Making> making;   // the block being made, for this thread to help
  std::exception_ptr failure;       // the helper's
  bool stop = false;                // this thread has failed: no more blocks
  std::thread helper([&] {
    for (std::size_t first = 0; first < count; first += block) {
      {
        // The block before taken (being written) before this one is made: two blocks held.
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return stop || !ready; });
        if (stop) return;
      }
      try {
        auto [results, pieces] = begin(first, std::min(count, first + block));
        auto m = std::make_shared<Making>();
        m->results = &results;
        m->pieces = pieces;
        {
          const std::lock_guard<std::mutex> lock(mutex);
          making = m;
        }
        changed.notify_all();
#pragma omp parallel num_threads(ahead_threads())
        take(*m, changed, mutex);
        {
          std::unique_lock<std::mutex> lock(mutex);
          changed.wait(lock, [&] { return m->done.load() == m->pieces; });  // this thread's pieces too
          making.reset();
        }
        m->failure.rethrow();
        const std::lock_guard<std::mutex> lock(mutex);
        ready.emplace(std::move(results));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        making.reset();
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
      for (;;) {
        std::shared_ptr<Making> help;
        {
          std::unique_lock<std::mutex> lock(mutex);
          changed.wait(lock, [&] {
            return ready.has_value() || failure || (making && making->next.load() < making->pieces);
          });
          if (ready) {
            results.swap(ready);
          } else if (failure) {
            std::rethrow_exception(failure);
          } else {
            help = making;
          }
        }
        if (results) break;
        take(*help, changed, mutex);
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
