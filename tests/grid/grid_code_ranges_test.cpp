// Ranges of whole octant rows (qtm_code_ranges.hpp): the splits of levels 0-9 into every number
// of parts up to the most allowed (all of them at the low levels), against the definition.
#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>
#include <vector>

#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"

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
