// radix_sort and sort_by_pair against std::stable_sort: keys of every width, sizes around the
// small-input cut and the items per thread, equal keys (stability), and thread counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "common/radix_sort.hpp"
#ifdef _OPENMP
#include <omp.h>
#endif

namespace qtmv {
namespace {

struct Item {
  std::uint64_t key;
  std::uint32_t order;  ///< the item's place before sorting
};

void expect_sorts_like_stable_sort(std::size_t n, int key_bits, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  // Few distinct keys at times, so that equal keys are common.
  const std::uint64_t span = key_bits == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << key_bits) - 1;
  const std::uint64_t top = seed % 3 == 0 ? std::min<std::uint64_t>(span, 7) : span;
  std::uniform_int_distribution<std::uint64_t> key(0, top);
  std::vector<Item> items(n);
  for (std::size_t k = 0; k < n; ++k) items[k] = {key(rng), static_cast<std::uint32_t>(k)};
  std::vector<Item> expected = items;
  std::stable_sort(expected.begin(), expected.end(), [](const Item& a, const Item& b) { return a.key < b.key; });
  radix_sort(items, key_bits, [](const Item& i) { return i.key; });
  ASSERT_EQ(items.size(), expected.size());
  for (std::size_t k = 0; k < n; ++k) {
    ASSERT_EQ(items[k].key, expected[k].key) << "n " << n << ", bits " << key_bits << ", place " << k;
    ASSERT_EQ(items[k].order, expected[k].order) << "n " << n << ", bits " << key_bits << ", place " << k;
  }
}

TEST(RadixSort, SortsStablyLikeStableSort) {
  std::uint64_t seed = 1;
  for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{511}, std::size_t{512}, std::size_t{2100}, std::size_t{1000},
                              std::size_t{16385}, std::size_t{100003}, std::size_t{400000}}) {
    for (const int bits : {1, 3, 11, 12, 27, 39, 45, 64}) expect_sorts_like_stable_sort(n, bits, seed++);
  }
}

TEST(RadixSort, AnyThreadCountGivesTheSameOrder) {
#ifdef _OPENMP
  const int before = omp_get_max_threads();
  for (const int threads : {1, 2, 3, 8}) {
    omp_set_num_threads(threads);
    expect_sorts_like_stable_sort(300007, 27, 99);
    expect_sorts_like_stable_sort(300007, 3, 102);
  }
  omp_set_num_threads(before);
#else
  expect_sorts_like_stable_sort(300007, 27, 99);
#endif
}

TEST(RadixSort, SortByPairOrdersByFirstThenSecond) {
  std::mt19937_64 rng(17);
  for (const std::size_t n : {std::size_t{100}, std::size_t{50000}}) {
    for (const int second_bits : {0, 5, 31}) {
      std::uniform_int_distribution<std::uint64_t> first(0, (std::uint64_t{1} << 27) - 1), second(0, (std::uint64_t{1} << second_bits) - 1);
      std::vector<std::pair<std::uint64_t, std::uint32_t>> items(n);
      for (auto& item : items) item = {first(rng) % (n / 4 + 1), static_cast<std::uint32_t>(second(rng))};
      std::vector<std::pair<std::uint64_t, std::uint32_t>> expected = items;
      std::sort(expected.begin(), expected.end());
      sort_by_pair(items, [](const auto& p) { return p.first; }, [](const auto& p) { return p.second; });
      EXPECT_EQ(items, expected) << "n " << n << ", second bits " << second_bits;
    }
  }
  // First keys all 0 beside second keys of 64 bits: one radix key of the second alone.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> seconds(1000);
  for (auto& item : seconds) item = {0, rng() | std::uint64_t{1} << 63};
  auto sorted_seconds = seconds;
  std::sort(sorted_seconds.begin(), sorted_seconds.end());
  sort_by_pair(seconds, [](const auto& p) { return p.first; }, [](const auto& p) { return p.second; });
  EXPECT_EQ(seconds, sorted_seconds);
  // Keys too wide for one radix key: the comparison sort's order.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> wide = {{~0ull, 3}, {1, ~0u}, {~0ull, 1}, {1, 0}};
  sort_by_pair(wide, [](const auto& p) { return p.first; }, [](const auto& p) { return p.second; });
  EXPECT_EQ(wide, (std::vector<std::pair<std::uint64_t, std::uint32_t>>{{1, 0}, {1, ~0u}, {~0ull, 1}, {~0ull, 3}}));
}

}  // namespace
}  // namespace qtmv
