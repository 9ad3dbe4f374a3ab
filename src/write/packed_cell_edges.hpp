// A site's outline cells with region edges (RegionTracer's lists), packed: each cell's code as
// its step from the cell before in the list, with its edge mask, in 1 to 10 bytes (mostly 1 to 3:
// a site's cells in code order are neighbours in a row, or a row apart). Hundreds of millions of
// cells at the finer levels, so 8 bytes a cell were gigabytes held for the whole write.
//
// An entry: the first byte holds the edge mask (bits 0-3), the value's low 2 bits (bits 4-5),
// whether the value is the code itself (bit 6: a list's first entry, or the first a thread of
// the bucketing wrote) rather than its step from the code before, and whether a byte follows
// (bit 7); each next byte 7 more bits of the value (low bits first) and whether a byte follows.
// The step is code - (code before + 1): codes only grow along a list.
#pragma once

#include <cstddef>
#include <cstdint>

#include "grid/qtm.hpp"

namespace qtmv::write {

/// Bits of a packed cell's edge mask (bit e: the cell's drawn edge e bounds the region).
constexpr int kPackedMaskBits = 4;
static_assert(grid::kMaxPolygonCorners <= kPackedMaskBits, "a drawn cell's edges fit the packed mask");

/// Where a packed list goes on: `after` is 0 at its start, then the last code written or read + 1.
/// Returns the bytes of the entry for `code` (> any code before it) and moves `after` past it.
inline std::size_t packed_cell_edges_bytes(grid::Code code, grid::Code& after) {
  std::uint64_t value = code - after;  // after == 0: the code itself
  after = code + 1;
  std::size_t bytes = 1;
  for (value >>= 2; value != 0; value >>= 7) ++bytes;
  return bytes;
}

/// Writes the entry for `code` and `mask` at `out` (packed_cell_edges_bytes of them) and moves
/// `after` past it. Returns the byte after the entry.
inline std::uint8_t* put_packed_cell_edges(std::uint8_t* out, grid::Code code, unsigned mask, grid::Code& after) {
  const bool whole = after == 0;
  std::uint64_t value = code - after;
  after = code + 1;
  auto byte = static_cast<std::uint8_t>(mask | (value & 3u) << 4 | (whole ? 0x40u : 0u));
  for (value >>= 2; value != 0; value >>= 7) {
    *out++ = static_cast<std::uint8_t>(byte | 0x80u);
    byte = static_cast<std::uint8_t>(value & 0x7Fu);
  }
  *out++ = byte;
  return out;
}

/// Reads a packed list [begin, end) entry by entry, in the order written.
class PackedCellEdgesReader {
 public:
  PackedCellEdgesReader(const std::uint8_t* begin, const std::uint8_t* end) : at_(begin), end_(end) {}
  /// The next entry's code and mask; false at the list's end.
  bool next(grid::Code& code, unsigned& mask) {
    if (at_ == end_) return false;
    std::uint8_t byte = *at_++;
    mask = byte & ((1u << kPackedMaskBits) - 1);
    const bool whole = (byte & 0x40u) != 0;
    std::uint64_t value = byte >> 4 & 3u;
    for (int shift = 2; (byte & 0x80u) != 0; shift += 7) {
      byte = *at_++;
      value |= std::uint64_t{byte & 0x7Fu} << shift;
    }
    code = whole ? value : after_ + value;
    after_ = code + 1;
    return true;
  }

 private:
  const std::uint8_t* at_;
  const std::uint8_t* end_;
  grid::Code after_ = 0;
};

}  // namespace qtmv::write
