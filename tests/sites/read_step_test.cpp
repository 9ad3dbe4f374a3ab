// run_step: the reading thread's share on the calling thread beside units any thread takes; each
// unit once; no more threads than units (and the share); the first exception comes out.
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "common/openmp_threads.hpp"
#include "sites/read_step.hpp"

namespace qtmv::sites {
namespace {

TEST(ReadStep, TheShareRunsOnTheCallingThreadAndEachUnitOnce) {
  for (const int threads : {1, 2, 8}) {
    for (const std::size_t units : {0u, 1u, 3u, 1000u}) {
      const std::thread::id caller = std::this_thread::get_id();
      std::thread::id share_thread;
      std::vector<std::atomic<int>> done(units);
      std::atomic<int> largest_team{0};
      run_step(
          threads, units, [&] { share_thread = std::this_thread::get_id(); },
          [&](std::size_t u) {
            done[u].fetch_add(1);
            int seen = largest_team.load();
            while (team_size() > seen && !largest_team.compare_exchange_weak(seen, team_size())) {
            }
          });
      EXPECT_EQ(share_thread, caller);
      for (std::size_t u = 0; u < units; ++u) EXPECT_EQ(done[u].load(), 1) << "unit " << u;
      EXPECT_LE(largest_team.load(), std::min<int>(threads, static_cast<int>(units) + 1));
    }
  }
}

// A step of points (three chunks of 65 536 at work, a vertex each, some empty) gets a few
// threads; one with lines, polygons or multipoints (more vertices than features) every thread;
// never more than the threads, never none.
TEST(ReadStep, PointsGetAThreadPerTheirNumberOthersEveryThread) {
  const std::size_t points = 3 * 65536;
  EXPECT_EQ(team_for_work(64, points, points), 7);
  EXPECT_EQ(team_for_work(64, points, points - 1000), 7);
  EXPECT_EQ(team_for_work(4, points, points), 4);
  EXPECT_EQ(team_for_work(64, points, points + 1), 64);
  EXPECT_EQ(team_for_work(64, 30, 4000), 64);
  EXPECT_EQ(team_for_work(32, 0, 0), 1);
  EXPECT_EQ(team_for_work(0, 30, 4000), 1);
  int last = 0;
  for (std::size_t features = 0; features < (std::size_t{1} << 20); features += 4099) {
    const int team = team_for_work(16, features, features);
    EXPECT_GE(team, last);
    EXPECT_LE(team, 16);
    last = team;
  }
  EXPECT_EQ(last, 16);
}

TEST(ReadStep, TheFirstExceptionComesOutAndTheRestStop) {
  for (const int threads : {1, 4}) {
    std::atomic<int> ran{0};
    EXPECT_THROW(run_step(
                     threads, 100, [] { throw std::runtime_error("share"); },
                     [&](std::size_t) { ran.fetch_add(1); }),
                 std::runtime_error);
    if (threads == 1) {
      EXPECT_EQ(ran.load(), 0);  // the share first: then no unit is started
    }
    ran = 0;
    try {
      run_step(
          threads, 10, [] {},
          [&](std::size_t u) {
            ran.fetch_add(1);
            if (u == 3) throw std::logic_error("unit 3");
          });
      FAIL() << "no exception";
    } catch (const std::logic_error& e) {
      EXPECT_STREQ(e.what(), "unit 3");
    }
    if (threads == 1) {
      EXPECT_EQ(ran.load(), 4);  // units in order: none after the failure
    }
  }
}

}  // namespace
}  // namespace qtmv::sites
