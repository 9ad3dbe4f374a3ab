// The painter's kernels (tree_label, paint, flags): the labels of a range of cells from the tree,
// each cell's walk that of tree_label_cell (label_tree.hpp), as the CPU's painter
// (src/label/cpu_painter.cpp) does. Included by painter_cuda.cu alone, which launches them (so no
// relocatable device code).
#pragma once

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/label_tree.hpp"
#include "label_launch.cuh"

namespace qtmv::label::cuda {

/// Labels (with distances and flags when asked) cell by cell, tree_label_cell for each code.
__global__ void tree_label_kernel(TreeView tree, grid::Code first, std::uint64_t count, std::int32_t* site,
                                  float* metres, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    tree_label_cell(tree, first + k, site + k, metres ? metres + k : nullptr, boundary ? boundary + k : nullptr);
  }
}

/// Labels (and boundary flags, no distances) in code order, written coalesced: each warp takes
/// spans of kPaintSpan = 128 x kPaintRounds consecutive outputs in turn, 4 per lane per round (one
/// 16-byte site store and one 4-byte flag store per lane). A span that lies in one row first
/// tabulates the jump cells it crosses (a row's cells fall into consecutive jump cells of one
/// jump row): the site of those in a uniform leaf and clean (jump_clean), so that their cells
/// take it with flag 0 from a shared-memory look-up. Other cells go one by one: a cell in a
/// uniform leaf gets the leaf's site, and flag 0 when it lies inside that leaf, else
/// kBoundaryPending; cells of list leaves are queued per warp in shared memory and then take
/// tree_label, 32 at a time, so that whole warps work on them; their flags are left pending too.
/// A span with pending flags is appended to pending_spans (*pending_count of them) for
/// tree_flag_kernel. Same labels as tree_label_kernel, and, once tree_flag_kernel has run, the
/// same flags.
constexpr int kPaintRounds = 8;
constexpr int kPaintWarps = kBlock / 32;
constexpr int kPaintSpan = 32 * 4 * kPaintRounds;  // outputs per warp
constexpr int kPaintTable = 256;                   // jump cells a one-row span may tabulate
static_assert(kPaintSpan == 4 * kBlock, "tree_flag_kernel's blocks take a span at a time");
constexpr std::uint64_t kPaintMinCells = std::uint64_t{1} << 21;  // fewer go cell by cell

/// Steps cell c (of a level with `rows` rows per octant) `step` codes on.
__device__ inline void advance_cell(grid::Cell& c, std::uint32_t step, std::uint32_t rows) {
  c.col += step;
  while (c.col > 2 * c.row) {
    c.col -= 2 * c.row + 1;
    if (++c.row == rows) {
      c.row = 0;
      ++c.octant;
    }
  }
}

/// tree_paint_kernel's work for span `span` (outputs [span, span + 1) x kPaintSpan) of one warp;
/// q and table: the warp's shared memory.
__device__ inline void paint_span(const TreeView& tree, const std::uint8_t* jump_clean, grid::Code first,
                                  std::uint64_t count, std::int32_t* site, std::uint8_t* boundary,
                                  std::uint32_t* pending_spans, unsigned int* pending_count, std::uint64_t span,
                                  std::uint16_t* q, std::int32_t* table) {
  const int level = tree.level, jl = tree.jump_level, k = level - jl;
  const unsigned lane = threadIdx.x & 31u;
  const std::uint64_t warp_out = span * kPaintSpan;
  int queued = 0;
  bool pending = false;
  const std::uint32_t rows = 1u << level;
  // The jump cell last looked up, its entry's node and whether it is clean.
  grid::Cell jump_cell{-1, 0, 0};
  int jump_level = 0, node_count = 0, node_value = 0;
  bool clean = false;
  auto look_up = [&](const grid::Cell& a) {
    if (a.col == jump_cell.col && a.row == jump_cell.row && a.octant == jump_cell.octant) return;
    jump_cell = a;
    const grid::Code jcode = grid::code_of(a, jl);
    const int2 e = __ldg(reinterpret_cast<const int2*>(tree.jump + jcode));
    jump_level = e.y;
    const int2 n = __ldg(reinterpret_cast<const int2*>(tree.nodes + e.x));
    node_count = n.x;
    node_value = n.y;
    clean = boundary && __ldg(jump_clean + jcode);
  };
  // The span's first cell, and the table when the span lies in one row.
  const grid::Cell c0 = grid::cell_of(first + warp_out, level);
  const std::uint64_t span_cells = count - warp_out < kPaintSpan ? count - warp_out : kPaintSpan;
  const std::uint32_t span_n = static_cast<std::uint32_t>(span_cells);
  const std::uint32_t local_row = c0.row & ((1u << k) - 1u);
  const std::uint32_t jc0 = grid::ancestor_col(c0.col, local_row, k);
  const bool one_row = c0.col + (span_cells - 1) <= 2 * c0.row;
  const bool tabulated =
      one_row && grid::ancestor_col(c0.col + static_cast<std::uint32_t>(span_cells - 1), local_row, k) - jc0 < kPaintTable;
  if (tabulated) {
    const std::uint32_t entries = grid::ancestor_col(c0.col + static_cast<std::uint32_t>(span_cells - 1), local_row, k) - jc0 + 1;
    for (std::uint32_t t = lane; t < entries; t += 32) {
      const grid::Code jcode = grid::code_of(grid::Cell{c0.octant, c0.row >> k, jc0 + t}, jl);
      const TreeNode n = tree.nodes[__ldg(&tree.jump[jcode].node)];
      table[t] = n.count == kUniform && (!boundary || __ldg(jump_clean + jcode)) ? n.value : -1;
    }
    __syncwarp();
  }
  grid::Cell c = c0;
  advance_cell(c, 4 * lane, rows);  // the lane's first cell of the round
  for (int round = 0; round < kPaintRounds; ++round) {
    const std::uint32_t local = static_cast<std::uint32_t>(round * 128) + 4 * lane;
    const std::uint64_t out = warp_out + local;
    std::int32_t s[4] = {-1, -1, -1, -1};
    std::uint32_t flags = 0;  // byte j: the flag of cell out + j (0 or kBoundaryPending)
    unsigned slow = 0;        // bit j: cell out + j is queued
    if (local < span_n) {
      unsigned todo = 0;  // bit j: cell out + j goes one by one
      if (tabulated) {
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if (local + j < span_n) {
            s[j] = table[grid::ancestor_col(c.col + j, local_row, k) - jc0];
            if (s[j] < 0) todo |= 1u << j;
          }
        }
      } else {
        todo = local + 4 <= span_n ? 0xfu : (1u << (span_n - local)) - 1u;
      }
      // Skipped as a whole in the common case, a span's table settling all four.
      if (todo != 0) {
        grid::Cell cc = c;
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if ((todo >> j) & 1u) {
            look_up(grid::ancestor(cc, level, jl));
            // find_leaf's walk, from the jump entry.
            int leaf_level = jump_level, leaf_count = node_count, leaf_value = node_value;
            while (leaf_count == kInternal) {
              const int2 n = __ldg(reinterpret_cast<const int2*>(tree.nodes + leaf_value +
                                                                 grid::child_digit(grid::ancestor(cc, level, leaf_level + 1))));
              leaf_count = n.x;
              leaf_value = n.y;
              ++leaf_level;
            }
            if (leaf_count == kUniform) {
              s[j] = leaf_value;
              if (boundary && !clean && !grid::interior_of_ancestor(cc, level, leaf_level)) {
                flags |= std::uint32_t{kBoundaryPending} << (8 * j);
              }
            } else {
              slow |= 1u << j;
              if (boundary) flags |= std::uint32_t{kBoundaryPending} << (8 * j);
            }
          }
          if (j < 3) advance_cell(cc, 1, rows);
        }
      }
      if (local + 4 <= span_n) {
        *reinterpret_cast<int4*>(site + out) = make_int4(s[0], s[1], s[2], s[3]);
        if (boundary) *reinterpret_cast<std::uint32_t*>(boundary + out) = flags;
      } else {
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if (local + j < span_n) {
            site[out + j] = s[j];
            if (boundary) boundary[out + j] = static_cast<std::uint8_t>(flags >> (8 * j));
          }
        }
      }
    }
    pending = pending || flags != 0;
    if (tabulated) {
      c.col += 128;  // the span's cells are all in this row
    } else {
      advance_cell(c, 128, rows);
    }
    // Queue the cells of list leaves in code order (warp-aggregated).
    if (__any_sync(0xffffffffu, slow != 0)) {
#pragma unroll
      for (int j = 0; j < 4; ++j) {
        const bool mine = (slow >> j) & 1u;
        const unsigned ballot = __ballot_sync(0xffffffffu, mine);
        if (mine) q[queued + __popc(ballot & ((1u << lane) - 1u))] = static_cast<std::uint16_t>(local + j);
        queued += __popc(ballot);
      }
    }
  }
  pending = __any_sync(0xffffffffu, pending);
  if (pending_spans && lane == 0 && pending) {
    pending_spans[atomicAdd(pending_count, 1u)] = static_cast<std::uint32_t>(span);
  }
  __syncwarp();  // the queue, before other lanes read it
  for (int e = static_cast<int>(lane); e < queued; e += 32) {
    const std::uint64_t out = warp_out + q[e];
    site[out] = tree_label(tree, grid::cell_of(first + out, level));
  }
  __syncwarp();  // the queue and the table, before the warp's next span
}

/// The paint pass: a grid that fills the device, each warp taking spans in turn from *next_span
/// (a span's work varies, lists and walks near boundaries, so fixed blocks would leave their
/// slots held by their slowest warp).
__global__ void __launch_bounds__(kBlock, 4) tree_paint_kernel(TreeView tree, const std::uint8_t* jump_clean,
                                                               grid::Code first, std::uint64_t count,
                                                               std::int32_t* site, std::uint8_t* boundary,
                                                               std::uint32_t* pending_spans,
                                                               unsigned int* pending_count,
                                                               unsigned int* next_span) {
  __shared__ std::uint16_t queue[kPaintWarps][kPaintSpan];
  __shared__ std::int32_t table[kPaintWarps][kPaintTable];
  const unsigned lane = threadIdx.x & 31u, warp = threadIdx.x >> 5;
  const std::uint64_t spans = (count + kPaintSpan - 1) / kPaintSpan;
  for (;;) {
    unsigned int span = 0;
    if (lane == 0) span = atomicAdd(next_span, 1u);
    span = __shfl_sync(0xffffffffu, span, 0);
    if (span >= spans) return;  // whole warps leave together: the ballots need all lanes
    paint_span(tree, jump_clean, first, count, site, boundary, pending_spans, pending_count, span, queue[warp],
               table[warp]);
  }
}

/// tree_flag_kernel's work for one warp: settles the pending flags (kBoundaryPending) among
/// outputs [warp_out, warp_out + 128), 4 per lane. The pending cells are queued in q in code order
/// (ballots) and then taken 32 at a time, so that whole warps do the neighbour look-ups rather
/// than the few lanes that hold one. A cell's flag is 1 when one of its three edge neighbours has
/// another site: a neighbour inside [first, first + count) reads the label tree_paint_kernel wrote
/// there; one outside is labelled from the tree (tree_label), and only when the neighbours inside
/// did not settle it, those look-ups being the dear ones.
__device__ inline void settle_flags(const TreeView& tree, grid::Code first, std::uint64_t count,
                                    const std::int32_t* site, std::uint8_t* boundary, std::uint64_t warp_out,
                                    std::uint8_t* q) {
  const unsigned lane = threadIdx.x & 31u;
  const std::uint64_t out = warp_out + 4 * lane;
  std::uint32_t flags = 0;
  if (out + 4 <= count) {
    flags = *reinterpret_cast<const std::uint32_t*>(boundary + out);
  } else {
    for (std::uint64_t j = 0; out + j < count; ++j) flags |= std::uint32_t{boundary[out + j]} << (8 * j);
  }
  int queued = 0;
#pragma unroll
  for (int j = 0; j < 4; ++j) {
    const bool mine = ((flags >> (8 * j)) & 0xffu) == kBoundaryPending;
    const unsigned ballot = __ballot_sync(0xffffffffu, mine);
    if (mine) q[queued + __popc(ballot & ((1u << lane) - 1u))] = static_cast<std::uint8_t>(4 * lane + j);
    queued += __popc(ballot);
  }
  __syncwarp();
  const int level = tree.level;
  for (int e = static_cast<int>(lane); e < queued; e += 32) {
    const std::uint64_t local = warp_out + q[e];
    const grid::Code code = first + local;
    const grid::Cell c = grid::cell_of(code, level);
    const std::int32_t own = __ldg(site + local);
    grid::Code nb[3];
    grid::neighbours(c, code, level, nb);
    bool flag = false, inside[3];
#pragma unroll
    for (int n = 0; n < 3; ++n) {
      inside[n] = nb[n] >= first && nb[n] - first < count;
      if (inside[n]) flag = flag || __ldg(site + (nb[n] - first)) != own;
    }
#pragma unroll
    for (int n = 0; n < 3; ++n) {
      if (!flag && !inside[n]) flag = tree_label(tree, grid::cell_of(nb[n], level)) != own;
    }
    boundary[local] = flag;
  }
  __syncwarp();  // the queue, before the warp's next use of it
}

/// The pending flags that tree_paint_kernel left, from the labels it wrote: a cell is a boundary
/// cell when one of its three edge neighbours has another site. A neighbour inside
/// [first, first + count) reads its label there; one outside is looked up in the tree
/// (tree_label, as tree_label_cell does). The paint spans with a pending flag are listed in
/// pending_spans (in no particular order: each span's flags depend on the labels alone); the
/// blocks take them a span at a time, each warp gathering the pending cells of its 128 outputs
/// and settling them 32 at a time.
__global__ void __launch_bounds__(kBlock) tree_flag_kernel(TreeView tree, grid::Code first, std::uint64_t count,
                                                           const std::int32_t* site, std::uint8_t* boundary,
                                                           const std::uint32_t* pending_spans,
                                                           const unsigned int* pending_count) {
  __shared__ std::uint8_t queue[kPaintWarps][128];
  const unsigned warp = threadIdx.x >> 5;
  const unsigned int spans = *pending_count;
  for (unsigned int k = blockIdx.x; k < spans; k += gridDim.x) {
    const std::uint64_t warp_out = static_cast<std::uint64_t>(pending_spans[k]) * kPaintSpan + warp * 128;
    if (warp_out < count) settle_flags(tree, first, count, site, boundary, warp_out, queue[warp]);
  }
}

/// Per jump cell: whether it is clean (jump_cell_clean), for the paint pass's tables.
__global__ void jump_clean_kernel(TreeView tree, std::uint64_t count, std::uint8_t* clean) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) clean[k] = jump_cell_clean(tree, k);
}

}  // namespace qtmv::label::cuda
