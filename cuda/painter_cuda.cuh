// The painter on the device (painter_cuda.cu), as the labeller's device API (label_cuda.cu)
// calls it: the labels and flags of a range of cells from the tree on the device, as the CPU's
// painter (src/label/cpu_painter.hpp) makes them.
#pragma once

#include <cstddef>
#include <cstdint>

#include "device_memory.cuh"
#include "grid/qtm.hpp"
#include "label/label_tree.hpp"

namespace qtmv::label::cuda {

/// The painter's grids on one device: enough resident blocks to fill it.
struct PaintGrids {
  unsigned int flag_blocks = 0;   ///< tree_flag_kernel's grid: enough resident blocks to fill the device
  unsigned int paint_blocks = 0;  ///< tree_paint_kernel's grid: its resident blocks
};

/// The grids for `device` (the current device).
PaintGrids paint_grids(int device);

/// The length of pending_spans (label_from_tree) for up to `cells` cells: one entry a paint span.
std::uint64_t paint_span_count(std::uint64_t cells);

/// Per jump cell of `tree`: jump_cell_clean (the paint pass's tables), its bytes added to *bytes.
device_memory::DeviceArray<std::uint8_t> mark_clean_jump_cells(const TreeView& tree, std::size_t* bytes,
                                                               device_memory::FaultStep injected);

/// Labels codes [first, first + count) from `tree` into site (and metres, boundary when not null),
/// on the default stream, not waited for. pending_spans (paint_span_count entries, used with
/// flags) and counters (2) are the paint pass's scratch.
void label_from_tree(const TreeView& tree, const std::uint8_t* jump_clean, const PaintGrids& grids, grid::Code first,
                     std::uint64_t count, std::int32_t* site, float* metres, std::uint8_t* boundary,
                     std::uint32_t* pending_spans, unsigned int* counters);

}  // namespace qtmv::label::cuda
