// The outline selection's device code: which cells of a labelled tile are outline cells
// (outline_cells.hpp: boundary cells and row ends), counted and written segment by segment.
// Included by outline_select_cuda.cu alone, which launches them (so no relocatable device code).
//
// Outline cells are sparse at fine levels (a few in 10^5 cells at level 19), so the tile is read
// once as flags, 16 cells a thread (one 16-byte load), and only the segments that hold outline
// cells are visited again to write them, in code order: a selection over every cell (CUB's
// over a counting iterator, the row-end test per cell) took 3x the labelling itself.
#pragma once

#include <cub/block/block_reduce.cuh>
#include <cub/block/block_scan.cuh>

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"
#include "label_launch.cuh"
#include "outline_select_cuda.cuh"

namespace qtmv::label::cuda {

/// Bit j set when tile cell from + j (j < n <= 16; code first + from + j) is an outline cell: its
/// flag is set, or it is the first or last cell of its octant row.
__device__ inline std::uint32_t outline_bits(const std::uint8_t* boundary, grid::Code first, std::uint64_t from,
                                             std::uint32_t n, int level) {
  std::uint32_t bits = 0;
  if (n == kSelectCellsPerThread && (reinterpret_cast<std::uintptr_t>(boundary + from) & 15) == 0) {
    const uint4 v = __ldg(reinterpret_cast<const uint4*>(boundary + from));
    const std::uint32_t words[4] = {v.x, v.y, v.z, v.w};
    for (int w = 0; w < 4; ++w) {
      for (int b = 0; b < 4; ++b) {
        if ((words[w] >> (8 * b)) & 0xffu) bits |= 1u << (4 * w + b);
      }
    }
  } else {
    for (std::uint32_t j = 0; j < n; ++j) {
      if (boundary[from + j] != 0) bits |= 1u << j;
    }
  }
  // Row ends: the rows that meet [code, end), each found from its first cell met.
  const grid::Code start = first + from, end = start + n;
  for (grid::Code code = start; code < end;) {
    const grid::Cell c = grid::cell_of(code, level);
    const grid::Code last = code - c.col + 2 * std::uint64_t{c.row};
    if (c.col == 0) bits |= 1u << (code - start);
    if (last < end) bits |= 1u << (last - start);
    code = last + 1;
  }
  return bits;
}

/// The flags of this thread's cells of segment `segment` (of a tile of `count` cells).
__device__ inline std::uint32_t thread_outline_bits(const std::uint8_t* boundary, grid::Code first,
                                                    std::uint64_t count, int level, std::uint64_t segment) {
  const std::uint64_t from = segment * kSelectSegmentCells + std::uint64_t{threadIdx.x} * kSelectCellsPerThread;
  if (from >= count) return 0;
  const std::uint64_t left = count - from;
  const std::uint32_t n = left < kSelectCellsPerThread ? static_cast<std::uint32_t>(left) : kSelectCellsPerThread;
  return outline_bits(boundary, first, from, n, level);
}

/// Outline cells per segment of tile cells [0, count): one block a segment, grid-stride.
__global__ void __launch_bounds__(kBlock) count_outline_kernel(const std::uint8_t* boundary, grid::Code first,
                                                               std::uint64_t count, int level, std::uint64_t segments,
                                                               std::uint64_t* per_segment) {
  using Reduce = cub::BlockReduce<std::uint32_t, kBlock>;
  __shared__ typename Reduce::TempStorage reduce;
  for (std::uint64_t s = blockIdx.x; s < segments; s += gridDim.x) {
    const std::uint32_t bits = thread_outline_bits(boundary, first, count, level, s);
    const std::uint32_t total = Reduce(reduce).Sum(static_cast<std::uint32_t>(__popc(bits)));
    if (threadIdx.x == 0) per_segment[s] = total;
    __syncthreads();  // before the shared storage is used again
  }
}

/// The outline cells of segments [segment_first, segment_end) in code order, at
/// out[offset[s] - offset[segment_first] + ...] (offset: the counts' exclusive sum).
__global__ void __launch_bounds__(kBlock) write_outline_kernel(const std::uint8_t* boundary, const std::int32_t* site,
                                                               grid::Code first, std::uint64_t count, int level,
                                                               std::uint64_t segment_first, std::uint64_t segment_end,
                                                               const std::uint64_t* offset, OutlineCell* out) {
  using Scan = cub::BlockScan<std::uint32_t, kBlock>;
  __shared__ typename Scan::TempStorage scan;
  const std::uint64_t base = offset[segment_first];
  for (std::uint64_t s = segment_first + blockIdx.x; s < segment_end; s += gridDim.x) {
    if (offset[s + 1] == offset[s]) continue;  // the same for the whole block: no outline cell
    const std::uint32_t bits = thread_outline_bits(boundary, first, count, level, s);
    std::uint32_t at = 0;
    Scan(scan).ExclusiveSum(static_cast<std::uint32_t>(__popc(bits)), at);
    OutlineCell* to = out + (offset[s] - base) + at;
    const std::uint64_t from = s * kSelectSegmentCells + std::uint64_t{threadIdx.x} * kSelectCellsPerThread;
    for (std::uint32_t rest = bits; rest != 0; rest &= rest - 1) {
      const std::uint64_t i = from + static_cast<std::uint32_t>(__ffs(rest) - 1);
      *to++ = OutlineCell(first + i, site[i], boundary[i] != 0);
    }
    __syncthreads();  // before the shared storage is used again
  }
}

}  // namespace qtmv::label::cuda
