// QTM topology: edge neighbours and the hierarchy between levels (QTM-SPEC.md).
#pragma once

#include "qtm_code.hpp"

namespace qtmv::grid {

/// Order of the three edge neighbours that neighbours() returns.
enum NeighbourSlot : int {
  kNeighbourLeft = 0,      ///< towards lower column (the octant's lon' = 0 side)
  kNeighbourRight = 1,     ///< towards higher column (the lon' = 90 side)
  kNeighbourVertical = 2,  ///< below an up cell (across the equator in the last row), above a down cell
};

/// The octant across the lon' = 0 edge of octant o.
QTMV_HD constexpr int octant_left_of(int o) { return o < 4 ? (o + 3) % 4 : 4 + (o - 4 + 1) % 4; }
/// The octant across the lon' = 90 edge of octant o.
QTMV_HD constexpr int octant_right_of(int o) { return o < 4 ? (o + 1) % 4 : 4 + (o - 4 + 3) % 4; }

/// The three edge neighbours of a valid cell, in NeighbourSlot order.
QTMV_HD inline void neighbours(const Cell& c, int level, Cell out[3]) {
  const std::uint32_t i = c.row, j = c.col;
  const std::uint32_t last_row = static_cast<std::uint32_t>(rows_per_octant(level) - 1);
  out[kNeighbourLeft] = j > 0 ? Cell{c.octant, i, j - 1} : Cell{octant_left_of(c.octant), i, 2 * i};
  out[kNeighbourRight] = j < 2 * i ? Cell{c.octant, i, j + 1} : Cell{octant_right_of(c.octant), i, 0};
  if ((j & 1u) != 0) {
    out[kNeighbourVertical] = Cell{c.octant, i - 1, j - 1};
  } else if (i < last_row) {
    out[kNeighbourVertical] = Cell{c.octant, i + 1, j + 1};
  } else {
    const int across = c.octant < 4 ? c.octant + 4 : c.octant - 4;
    out[kNeighbourVertical] = Cell{across, i, 2 * (last_row - j / 2)};
  }
}

/// The neighbours' codes of cell c, whose code is `code`. Inside the octant they follow from the
/// code (row i starts at code i^2 of its octant): left code - 1, right code + 1, above a down
/// cell code - 2i, below an up cell code + 2i + 2; only cells on the octant's edges need the cells.
QTMV_HD inline void neighbours(const Cell& c, Code code, int level, Code out[3]) {
  const std::uint64_t i = c.row, j = c.col;
  const bool inside = j > 0 && j < 2 * i && ((j & 1u) != 0 || i + 1 < rows_per_octant(level));
  if (inside) {
    out[kNeighbourLeft] = code - 1;
    out[kNeighbourRight] = code + 1;
    out[kNeighbourVertical] = (j & 1u) != 0 ? code - 2 * i : code + 2 * i + 2;
    return;
  }
  Cell n[3];
  neighbours(c, level, n);
  for (int k = 0; k < 3; ++k) out[k] = code_of(n[k], level);
}

QTMV_HD inline void neighbours(Code code, int level, Code out[3]) { neighbours(cell_of(code, level), code, level, out); }

/// The parent at level - 1 (level >= 1): the cell of level - 1 that holds the child's
/// centre. The planar test of the spec is done in integers, so it is exact.
QTMV_HD inline Cell parent(const Cell& c) {
  const std::int64_t i = c.row, a = c.col / 2;
  const std::int64_t pi = i / 2, pa = a / 2;
  // Centre of the child at the parent's level, in units of 1/6 of a parent row:
  // up w = (3a+1)/6, v = (3i+2)/6; down w = (3a+2)/6, v = (3i+1)/6.
  const std::int64_t fw6 = (is_up(c) ? 3 * a + 1 : 3 * a + 2) - 6 * pa;
  const std::int64_t fv6 = (is_up(c) ? 3 * i + 2 : 3 * i + 1) - 6 * pi;
  std::int64_t pj = fw6 <= fv6 ? 2 * pa : 2 * pa + 1;
  if (pj > 2 * pi) pj = 2 * pi;
  return {c.octant, static_cast<std::uint32_t>(pi), static_cast<std::uint32_t>(pj)};
}

QTMV_HD inline Code parent(Code code, int level) { return code_of(parent(cell_of(code, level)), level - 1); }

/// The four children at level + 1 (level < kMaxLevel).
QTMV_HD inline void children(const Cell& c, Cell out[4]) {
  const std::uint32_t i = c.row, a = c.col / 2;
  if (is_up(c)) {
    out[0] = {c.octant, 2 * i, 4 * a};
    out[1] = {c.octant, 2 * i + 1, 4 * a};
    out[2] = {c.octant, 2 * i + 1, 4 * a + 1};
    out[3] = {c.octant, 2 * i + 1, 4 * a + 2};
  } else {
    out[0] = {c.octant, 2 * i, 4 * a + 1};
    out[1] = {c.octant, 2 * i, 4 * a + 2};
    out[2] = {c.octant, 2 * i, 4 * a + 3};
    out[3] = {c.octant, 2 * i + 1, 4 * a + 3};
  }
}

QTMV_HD inline void children(Code code, int level, Code out[4]) {
  Cell ch[4];
  children(cell_of(code, level), ch);
  for (int k = 0; k < 4; ++k) out[k] = code_of(ch[k], level + 1);
}

}  // namespace qtmv::grid
