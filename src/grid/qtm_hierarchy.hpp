// The QTM hierarchy in cell coordinates: ancestors, child digits, quadtree order, descendants.
// Shifts and masks only, one body for host and device code (QTMV_HD).
//
// Layout (docs/QTM-SPEC.md): cell (octant, row i, col j) of level L has 2 i + 1
// columns in its row; even columns are "up" cells, odd "down". Row i of level L - k holds rows
// i 2^k .. i 2^k + 2^k - 1 below it. The invariants the tests sweep (tests/grid/
// grid_hierarchy_test.cpp): ancestor() equals grid::parent() applied k times; child_digit() is the
// cell's index in grid::children(); quadtree_key() numbers the cells of every node consecutively.
#pragma once

#include <cmath>
#include <cstdint>

#include "qtm_code.hpp"
#include "qtm_host_device.hpp"
#include "qtm_topology.hpp"

namespace qtmv::grid {

/// ancestor()'s column, k levels up, of the cell in column `col` of local row `local_row`: the
/// paint kernel uses it alone for the cells of one row.
QTMV_HD inline std::uint32_t ancestor_col(std::uint32_t col, std::uint32_t local_row, int k) {
  return ((col >> (k + 1)) << 1) | ((col & ((2u << k) - 1u)) > 2 * local_row ? 1u : 0u);
}

/// The ancestor at level `to` (<= from) of cell c of level `from`. Row r of an ancestor k = from - to
/// levels up holds rows r 2^k .. r 2^k + 2^k - 1 below it; in the local row lr of those, the up
/// ancestor (column 2a) holds columns a 2^(k+1) .. a 2^(k+1) + 2 lr and the down ancestor (column
/// 2a + 1) the rest of the block of 2^(k+1) columns. Shifts and masks only (the tests compare it
/// with grid::parent applied k times).
QTMV_HD inline Cell ancestor(const Cell& c, int from, int to) {
  const int k = from - to;
  return {c.octant, c.row >> k, ancestor_col(c.col, c.row & ((1u << k) - 1u), k)};
}

/// Position (0..3) of cell c among its parent's children, in grid::children() order.
QTMV_HD inline int child_digit(const Cell& c) {
  const std::uint32_t m = c.col & 3u;
  if ((c.row & 1u) == 0) return m == 0 ? 0 : static_cast<int>(m) - 1;
  return m == 3 ? 3 : static_cast<int>(m) + 1;
}

/// Position of cell c (of `level`) in quadtree order: the octant, then the child digits from
/// level 1 down, 2 bits each (3 + 2 level bits). The cells below any node have consecutive keys,
/// those of node a (level l) being [key(a) << 2 (level - l), (key(a) + 1) << 2 (level - l)).
QTMV_HD inline std::uint64_t quadtree_key(const Cell& c, int level) {
  std::uint64_t key = static_cast<std::uint64_t>(c.octant);
  for (int l = 1; l <= level; ++l) key = (key << 2) | static_cast<std::uint64_t>(child_digit(ancestor(c, level, l)));
  return key;
}

/// The cell of `level` whose quadtree_key is `key` (its inverse).
QTMV_HD inline Cell cell_of_quadtree_key(std::uint64_t key, int level) {
  Cell c{static_cast<int>(key >> (2 * level)), 0, 0};
  for (int l = level - 1; l >= 0; --l) {
    Cell ch[4];
    children(c, ch);
    c = ch[(key >> (2 * l)) & 3u];
  }
  return c;
}

/// True when all three edge neighbours of cell c (level `level`) lie in c's ancestor at
/// `leaf_level`, so that a uniform leaf settles c's boundary flag without looking further.
/// In ancestor()'s terms (local row lr of 2^k, column offset in the block of 2^(k+1)), an up
/// ancestor holds offsets 0 .. 2 lr and a down one 2 lr + 1 .. 2^(k+1) - 1. The first and last cell
/// of such a run have a neighbour outside, and so do the up cells of an up ancestor's last row
/// (below) and the down cells of a down ancestor's first row (above).
QTMV_HD inline bool interior_of_ancestor(const Cell& c, int level, int leaf_level) {
  const int k = level - leaf_level;
  const std::uint32_t lr = c.row & ((1u << k) - 1u);
  const std::uint32_t offset = c.col & ((2u << k) - 1u);
  if (offset <= 2 * lr) {  // up ancestor
    return offset > 0 && offset < 2 * lr && !(is_up(c) && lr == (1u << k) - 1u);
  }
  return offset > 2 * lr + 1 && offset < (2u << k) - 1 && !(!is_up(c) && lr == 0);
}

/// The m-th (0 <= m < 4^k) of the cells k levels below cell a, row by row from a's apex: local
/// row rr holds 2 rr + 1 cells (the jump cells' painting order on the GPU).
QTMV_HD inline Cell descendant(const Cell& a, int k, std::uint32_t m) {
  std::uint32_t rr = static_cast<std::uint32_t>(sqrtf(static_cast<float>(m)));
  while (rr * rr > m) --rr;
  while ((rr + 1) * (rr + 1) <= m) ++rr;
  const std::uint32_t cc = m - rr * rr;
  const std::uint32_t side = 1u << k, base = (a.col / 2) << (k + 1);
  const bool up = is_up(a);
  const std::uint32_t r = up ? rr : side - 1 - rr;
  return {a.octant, (a.row << k) + r, up ? base + cc : base + 2 * r + 1 + cc};
}

/// Row r (0 .. 2^k - 1, from the apex) of the cells k levels below `cell`, at `level`: the codes
/// [first, last] it holds (consecutive in code order), and the code of that row's column 0 (for a
/// cell's parity: up cells are an even distance from it).
struct RowCodes {
  Code first, last, row_start;
};
QTMV_HD inline RowCodes row_codes_below(const Cell& cell, int k, std::uint64_t r, int level) {
  const std::uint64_t row = (std::uint64_t{cell.row} << k) + r, rows = std::uint64_t{1} << k;
  const std::uint64_t base = std::uint64_t{cell.col / 2} << (k + 1);
  const Code start = static_cast<std::uint64_t>(cell.octant) * cells_per_octant(level) + row * row;
  return is_up(cell) ? RowCodes{start + base, start + base + 2 * r, start}
                     : RowCodes{start + base + 2 * r + 1, start + base + 2 * rows - 1, start};
}

/// Steps cell c of `level` to the next cell in code order (column, then row, then octant).
QTMV_HD inline void next_in_code_order(Cell& c, int level) {
  if (c.col < 2 * c.row) {
    ++c.col;
  } else if (c.row + 1 < rows_per_octant(level)) {
    ++c.row;
    c.col = 0;
  } else {
    ++c.octant;
    c.row = 0;
    c.col = 0;
  }
}

}  // namespace qtmv::grid
