// Contiguous ranges of cell codes that start at the first cell of an octant row: the parts a
// level is split into for tile jobs and for several GPUs.
//
// Why row starts: codes run row by row (qtm_code.hpp), and the first cell of every row is an
// outline cell (label/outline_cells.hpp). So the outline cells of a range that starts at a row
// start settle the site of every cell in it, and the products of such ranges (outline cells,
// cells per site) join by concatenation and addition into exactly the products of the level.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "qtm_code.hpp"

namespace qtmv::grid {

/// The codes [first, end) of one level.
struct CodeRange {
  Code first = 0;
  Code end = 0;
  std::uint64_t size() const { return end - first; }
  bool operator==(const CodeRange& o) const { return first == o.first && end == o.end; }
};

/// The whole level as a range.
inline CodeRange whole_level(int level) { return {0, cell_count(level)}; }

/// The code of the first cell of the row that holds `code` (a valid code of the level).
inline Code row_start_of(Code code, int level) {
  const Cell c = cell_of(code, level);
  return code - c.col;
}

/// True when `code` is the first cell of its row (or the level's end, cell_count(level)).
inline bool is_row_start(Code code, int level) {
  return code == cell_count(level) || (is_valid_code(code, level) && cell_of(code, level).col == 0);
}

/// True when `range` is non-empty and both its ends are row starts of the level (whole rows).
inline bool is_rows(CodeRange range, int level) {
  return range.first < range.end && is_row_start(range.first, level) && is_row_start(range.end, level);
}

/// True when some of the rows of `level` under `cell` (of level cell_level <= level) hold a code
/// of `range`: the cells under a cell fill rows [row * 2^k, (row + 1) * 2^k) of its octant, k =
/// level - cell_level, each row partly, and those rows are one run of codes. Exact for ranges of
/// whole rows; for other ranges it may say true for a cell none of whose own cells is in range.
inline bool rows_meet(CodeRange range, const Cell& cell, int cell_level, int level) {
  const int k = level - cell_level;
  const Code octant_first = static_cast<Code>(cell.octant) * cells_per_octant(level);
  const std::uint64_t row_first = std::uint64_t{cell.row} << k, row_end = row_first + (std::uint64_t{1} << k);
  return octant_first + row_end * row_end > range.first && octant_first + row_first * row_first < range.end;
}

/// The most parts split_in_rows accepts at a level: a part gets at least as many cells as the
/// longest row (2^(level+1) - 1), so that no part is empty.
inline int most_row_parts(int level) {
  const std::uint64_t most = cell_count(level) / (2 * rows_per_octant(level));
  return most > 0x7fffffff ? 0x7fffffff : static_cast<int>(most);
}

/// Splits `range` (both ends row starts) into `parts` contiguous, non-empty ranges of about
/// equal cells, each starting at a row start, in code order. Throws std::invalid_argument for
/// parts < 1 or more parts than the range's rows allow.
inline std::vector<CodeRange> split_in_rows(CodeRange range, int parts, int level) {
  if (parts < 1) throw std::invalid_argument("a range is split into at least one part");
  if (!is_rows(range, level)) {
    throw std::invalid_argument("the range to split must start and end at row starts");
  }
  std::vector<CodeRange> out;
  Code first = range.first;
  for (int k = 1; k <= parts; ++k) {
    // The k-th equal share's end, moved back to its row's start.
    const Code share = range.first + static_cast<Code>(static_cast<long double>(range.size()) * k / parts);
    const Code end = k == parts ? range.end : row_start_of(share, level);
    if (end <= first) {
      throw std::invalid_argument(std::to_string(parts) + " parts are more than the " + std::to_string(range.size()) +
                                  " cells of the range allow at level " + std::to_string(level));
    }
    out.push_back({first, end});
    first = end;
  }
  return out;
}

/// Tile `index` (1..count) of a level split into `count` tiles by split_in_rows.
inline CodeRange tile_range(int level, int index, int count) {
  if (count < 1 || count > most_row_parts(level)) {
    throw std::invalid_argument("level " + std::to_string(level) + " splits into 1 to " +
                                std::to_string(most_row_parts(level)) + " tiles, not " + std::to_string(count));
  }
  if (index < 1 || index > count) {
    throw std::invalid_argument("tile " + std::to_string(index) + " is not one of 1.." + std::to_string(count));
  }
  return split_in_rows(whole_level(level), count, level)[static_cast<std::size_t>(index - 1)];
}

}  // namespace qtmv::grid
