// The run's default thread count (ScopedDefaultThreads): what thread_count(0) gives, its nesting
// and restoring, and the teams of the parallel regions and sorts that follow it.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <vector>

#include "common/openmp_threads.hpp"
#include "common/parallel_sort.hpp"
#include "common/radix_sort.hpp"

namespace qtmv {
namespace {

TEST(ScopedDefaultThreads, SetsNestsAndRestoresTheDefault) {
  const int before = thread_count(0);
  {
    const ScopedDefaultThreads three(3);
    EXPECT_EQ(thread_count(0), 3);
    EXPECT_EQ(thread_count(5), 5);  // a count given wins
    {
      const ScopedDefaultThreads unchanged(0);
      EXPECT_EQ(thread_count(0), 3);
      const ScopedDefaultThreads one(1);
      EXPECT_EQ(thread_count(0), 1);
    }
    EXPECT_EQ(thread_count(0), 3);
  }
  EXPECT_EQ(thread_count(0), before);
}

#ifdef _OPENMP
TEST(ScopedDefaultThreads, LimitsTheTeamsOfTheRegionsThatAskForIt) {
  for (const int limit : {1, 2, 3}) {
    const ScopedDefaultThreads scope(limit);
    std::atomic<int> most{0};
#pragma omp parallel num_threads(thread_count(0))
    {
      int seen = most.load();
      while (team_size() > seen && !most.compare_exchange_weak(seen, team_size())) {
      }
    }
    EXPECT_LE(most.load(), limit);
    EXPECT_GE(most.load(), 1);
  }
}
#endif

TEST(ScopedDefaultThreads, SortsGiveTheSameOrderUnderAnyLimit) {
  std::vector<std::uint64_t> keys(100000);
  std::uint64_t x = 88172645463325252ull;
  for (auto& k : keys) {
    x ^= x << 13, x ^= x >> 7, x ^= x << 17;
    k = x >> 20;
  }
  std::vector<std::uint64_t> radix_all = keys, parallel_all = keys;
  radix_sort(radix_all, 44, [](std::uint64_t k) { return k; });
  parallel_sort(parallel_all.begin(), parallel_all.end(), std::less<std::uint64_t>());
  for (const int limit : {1, 2, 5}) {
    const ScopedDefaultThreads scope(limit);
    std::vector<std::uint64_t> radix = keys, parallel = keys;
    radix_sort(radix, 44, [](std::uint64_t k) { return k; });
    parallel_sort(parallel.begin(), parallel.end(), std::less<std::uint64_t>());
    EXPECT_EQ(radix, radix_all) << limit << " threads";
    EXPECT_EQ(parallel, parallel_all) << limit << " threads";
  }
  EXPECT_TRUE(std::is_sorted(radix_all.begin(), radix_all.end()));
}

}  // namespace
}  // namespace qtmv
