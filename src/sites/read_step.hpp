// A step of the read: the reading thread's share of it (GDAL's reads and the reports in feature
// order, on the calling thread, where GDAL's messages are caught and the caller's callbacks
// run) beside units of work that the team's threads take first come first served, the reading
// thread too once its share is done. A step's team has no more threads than it has units (and
// the reading thread), nor more than its work is worth (team_for_work), so that more threads
// never cost more than the work is worth.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>

#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"

namespace qtmv::sites {

/// The points a step's team is given a thread for (beyond the first): a step of points (three
/// chunks of 65 536 at work) gets 7 threads. Measured on 32 cores (bench/RESULTS.md, session 26),
/// 1M points read with 8 GDAL readers: teams of 4 and 8 read a GeoPackage in 0.64-0.80 s, teams
/// of 16 and 32 in 1.0-1.2 s (the team's threads crowd the readers, and give back the features
/// those made); a CSV in 0.76-0.83 s either way.
constexpr std::size_t kPointsPerThread = std::size_t{1} << 15;

/// A step's threads for its chunks' `features` with `vertices` in all: for points (a vertex a
/// feature at most) 1 + features / kPointsPerThread; every thread once there is more (lines,
/// polygons, multipoints: their covers' work follows their extent at the level, not their
/// vertices). At most `threads`, at least 1.
inline int team_for_work(int threads, std::size_t features, std::size_t vertices) {
  const std::size_t all = static_cast<std::size_t>(std::max(threads, 1));
  return static_cast<int>(vertices > features ? all : std::min(all, 1 + features / kPointsPerThread));
}

/// Runs share() on the calling thread and unit(u) for u in [0, units) on up to `threads`
/// threads (the calling thread among them), each unit once; an exception from either comes out
/// of here (the first one; the units not started by then are left).
template <class Share, class Unit>
void run_step(int threads, std::size_t units, const Share& share, const Unit& unit) {
  FirstException failure;
  const int team = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(std::max(threads, 1)), units + 1));
  std::atomic<std::size_t> next{0};
#pragma omp parallel num_threads(team) if (team > 1)
  {
    if (thread_index() == 0) failure.run(share);
    for (std::size_t u = next.fetch_add(1, std::memory_order_relaxed); u < units;
         u = next.fetch_add(1, std::memory_order_relaxed)) {
      failure.run([&] { unit(u); });
    }
  }
  failure.rethrow();
}

}  // namespace qtmv::sites
