// QTM cell codes: layout, invariants and conversions to (octant, row, column).
//
// The grid is the octahedral quaternary triangular mesh of docs/QTM-SPEC.md.
//
// Layout of a code at level L (0 <= L <= kMaxLevel), with I = 2^L rows per octant and
// P = 4^L cells per octant:
//
//     code = octant * P + K,     K = row * row + col        (the paper's eq. 2 and eq. 1)
//
//   octant  0..7   0-3 north (0 at lon [0, 90), then eastwards), 4-7 south (4 under 0, ...)
//   row     0..I-1 counted from the pole; row i holds 2i+1 cells
//   col     0..2i  even: an "up" cell (apex towards the pole); odd: a "down" cell
//
// Invariants:
//   - codes of a level are dense: exactly 0 .. 8*4^L - 1, so a code indexes an array;
//   - the level is not stored in the code: every function takes it as an argument;
//   - within an octant, codes run row by row from the pole, west to east in local longitude;
//   - codes need 64 bits from level 15 on (8 * 4^15 > 2^32); level 24 uses 51 bits.
#pragma once

#include <cmath>
#include <cstdint>

#include "qtm_host_device.hpp"

namespace qtmv::grid {

using Code = std::uint64_t;

constexpr int kMinLevel = 0;
constexpr int kMaxLevel = 24;
constexpr int kOctants = 8;
/// Returned by functions that cannot give a cell (a coordinate that is NaN, say).
constexpr Code kInvalidCode = ~Code{0};

/// A cell by its octant (0..7), row (0..2^L - 1) and column (0..2 row).
struct Cell {
  int octant;
  std::uint32_t row;
  std::uint32_t col;
};

QTMV_HD constexpr bool is_valid_level(int level) { return level >= kMinLevel && level <= kMaxLevel; }

/// Rows per octant at a level: I = 2^L.
QTMV_HD constexpr std::uint64_t rows_per_octant(int level) { return std::uint64_t{1} << level; }

/// Cells per octant at a level: P = 4^L.
QTMV_HD constexpr std::uint64_t cells_per_octant(int level) { return std::uint64_t{1} << (2 * level); }

/// Cells of the whole globe at a level: 8 * 4^L.
QTMV_HD constexpr std::uint64_t cell_count(int level) { return std::uint64_t{8} << (2 * level); }

/// The width (bits) of the codes of `level`: they lie below cell_count(level) = 2^(3 + 2 level).
QTMV_HD constexpr int code_bits(int level) { return 3 + 2 * level; }

QTMV_HD constexpr bool is_valid_code(Code code, int level) {
  return is_valid_level(level) && code < cell_count(level);
}

QTMV_HD constexpr bool is_valid_cell(const Cell& c, int level) {
  return is_valid_level(level) && c.octant >= 0 && c.octant < kOctants && c.row < rows_per_octant(level) &&
         c.col <= 2 * c.row;
}

QTMV_HD constexpr bool is_up(const Cell& c) { return (c.col & 1u) == 0; }

/// Code of a valid cell.
QTMV_HD constexpr Code code_of(const Cell& c, int level) {
  return static_cast<Code>(c.octant) * cells_per_octant(level) + std::uint64_t{c.row} * c.row + c.col;
}

/// Cell of a valid code.
QTMV_HD inline Cell cell_of(Code code, int level) {
  // cells_per_octant is 4^level: a shift and a mask, not a 64-bit division (slow on GPUs).
  const int octant = static_cast<int>(code >> (2 * level));
  const std::uint64_t k = code & (cells_per_octant(level) - 1);
  // k < 2^48, so the double square root is within one of the integer one; correct it.
  std::uint64_t row = static_cast<std::uint64_t>(sqrt(static_cast<double>(k)));
  while (row * row > k) --row;
  while ((row + 1) * (row + 1) <= k) ++row;
  return {octant, static_cast<std::uint32_t>(row), static_cast<std::uint32_t>(k - row * row)};
}

}  // namespace qtmv::grid
