// Ranges of whole octant rows (qtm_code_ranges.hpp): the splits of levels 0-9 into every number
// of parts up to the most allowed (all of them at the low levels), against the definition; key
// ranges given to their lowest owner (qtm_key_ranges.hpp), against each key one by one.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <random>
#include <stdexcept>
#include <vector>

#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "grid/qtm_key_ranges.hpp"

namespace qtmv::grid {
namespace {

TEST(GridCodeRanges, RowStartsAreTheFirstCellsOfTheRows) {
  for (int level = 0; level <= 6; ++level) {
    Cell c{0, 0, 0};
    for (Code code = 0; code < cell_count(level); ++code, next_in_code_order(c, level)) {
      ASSERT_EQ(is_row_start(code, level), c.col == 0) << code;
      ASSERT_EQ(row_start_of(code, level), code - c.col) << code;
    }
    EXPECT_TRUE(is_row_start(cell_count(level), level));
    EXPECT_FALSE(is_row_start(cell_count(level) + 1, level));
  }
}

TEST(GridCodeRanges, SplitsCoverTheLevelInRowsOfAboutEqualCells) {
  for (int level = 0; level <= 9; ++level) {
    const int most = most_row_parts(level);
    const std::uint64_t longest_row = 2 * rows_per_octant(level) - 1;
    for (int parts = 1; parts <= most; parts += level <= 5 ? 1 : 37) {
      SCOPED_TRACE("level " + std::to_string(level) + ", " + std::to_string(parts) + " parts");
      const std::vector<CodeRange> split = split_in_rows(whole_level(level), parts, level);
      ASSERT_EQ(split.size(), static_cast<std::size_t>(parts));
      EXPECT_EQ(split.front().first, 0u);
      EXPECT_EQ(split.back().end, cell_count(level));
      const double share = static_cast<double>(cell_count(level)) / parts;
      for (std::size_t k = 0; k < split.size(); ++k) {
        ASSERT_LT(split[k].first, split[k].end);
        if (k > 0) {
          ASSERT_EQ(split[k].first, split[k - 1].end);
        }
        ASSERT_TRUE(is_row_start(split[k].first, level) && is_row_start(split[k].end, level));
        // Each end is its equal share's, moved back by less than a row.
        EXPECT_LE(static_cast<double>(split[k].size()), share + static_cast<double>(longest_row) + 1);
        EXPECT_GE(static_cast<double>(split[k].size()), share - static_cast<double>(longest_row) - 1);
        ASSERT_EQ(tile_range(level, static_cast<int>(k) + 1, parts), split[k]);
      }
    }
    EXPECT_THROW(tile_range(level, 1, most + 1), std::invalid_argument);
    EXPECT_THROW(tile_range(level, 0, 1), std::invalid_argument);
    EXPECT_THROW(tile_range(level, 2, 1), std::invalid_argument);
  }
  EXPECT_THROW(split_in_rows({2, 8}, 1, 1), std::invalid_argument);  // 2 is not a row start at level 1
}

TEST(GridCodeRanges, SplitsOfARangeStayInIt) {
  const int level = 7;
  const std::vector<CodeRange> halves = split_in_rows(whole_level(level), 2, level);
  for (const CodeRange& half : halves) {
    const std::vector<CodeRange> parts = split_in_rows(half, 5, level);
    EXPECT_EQ(parts.front().first, half.first);
    EXPECT_EQ(parts.back().end, half.end);
  }
}

}  // namespace
}  // namespace qtmv::grid

// Key ranges given to their lowest owner: against each key's lowest owner found one by one, for
// disjoint ranges (the common case: one polygon's cover), runs of overlapping ones, and both.

namespace qtmv::grid {
namespace {

TEST(KeyRanges, LowestOwnerPartitionGivesEachKeyItsLowestOwner) {
  std::mt19937_64 rng(7);
  for (int round = 0; round < 300; ++round) {
    const int mode = round % 3;  // 0: disjoint, 1: overlapping, 2: mixed
    std::vector<KeyRange> ranges;
    std::uint64_t at = rng() % 5;
    const int n = 1 + static_cast<int>(rng() % 40);
    for (int k = 0; k < n; ++k) {
      const std::uint64_t length = 1 + rng() % 6;
      const auto owner = static_cast<std::int32_t>(rng() % 5);
      if (mode == 0 || (mode == 2 && rng() % 2 == 0)) {
        ranges.push_back({at, at + length - 1, owner});
        at += length + rng() % 3;  // next to it, or a gap
      } else {
        const std::uint64_t first = at > 8 ? at - rng() % 8 : at;
        ranges.push_back({first, first + length + rng() % 10, owner});
        at = std::max(at, ranges.back().last + 1 - rng() % 3);
      }
    }
    std::map<std::uint64_t, std::int32_t> lowest;
    for (const KeyRange& r : ranges) {
      for (std::uint64_t q = r.first; q <= r.last; ++q) {
        auto it = lowest.find(q);
        if (it == lowest.end() || r.owner < it->second) lowest[q] = r.owner;
      }
    }
    const std::vector<KeyRange> got = lowest_owner_partition(ranges);
    std::map<std::uint64_t, std::int32_t> given;
    for (std::size_t k = 0; k < got.size(); ++k) {
      ASSERT_LE(got[k].first, got[k].last);
      if (k > 0) {
        ASSERT_LT(got[k - 1].last, got[k].first) << "round " << round << ": not sorted and disjoint";
        ASSERT_FALSE(got[k - 1].owner == got[k].owner && got[k - 1].last + 1 == got[k].first)
            << "round " << round << ": neighbours of one owner not merged";
      }
      for (std::uint64_t q = got[k].first; q <= got[k].last; ++q) given[q] = got[k].owner;
    }
    ASSERT_EQ(given, lowest) << "round " << round << " (mode " << mode << ")";
  }
}

}  // namespace
}  // namespace qtmv::grid
