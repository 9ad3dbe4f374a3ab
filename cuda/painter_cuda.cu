// The painter's launches (the kernels: painter_kernels.cuh). The maths is the QTMV_HD code of
// src/label (label_math.hpp, label_tree.hpp), compiled here without FMA contraction (qtmv::grid
// adds --fmad=false), so the labels are those of the CPU path bit for bit.
#include "painter_cuda.cuh"

#include <stdexcept>

#include "label_launch.cuh"
#include "painter_kernels.cuh"

namespace qtmv::label::cuda {

using device_memory::DeviceArray;
using device_memory::FaultStep;

PaintGrids paint_grids(int device) {
  PaintGrids grids;
  int sms = 0;
  QTMV_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
  grids.flag_blocks = static_cast<unsigned int>(sms) * 8;
  int per_sm = 0;
  QTMV_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, tree_paint_kernel, kBlock, 0));
  grids.paint_blocks = static_cast<unsigned int>(sms) * static_cast<unsigned int>(per_sm > 0 ? per_sm : 1);
  return grids;
}

std::uint64_t paint_span_count(std::uint64_t cells) { return (cells + kPaintSpan - 1) / kPaintSpan; }

DeviceArray<std::uint8_t> mark_clean_jump_cells(const TreeView& tree, std::size_t* bytes, FaultStep injected) {
  const std::uint64_t count = grid::cell_count(tree.jump_level);
  DeviceArray<std::uint8_t> jump_clean = device_memory::device_alloc<std::uint8_t>(count, bytes, injected);
  jump_clean_kernel<<<blocks_for(count), kBlock>>>(tree, count, jump_clean.get());
  QTMV_CUDA_CHECK_LAUNCH("jump_clean_kernel");
  QTMV_CUDA_CHECK(cudaDeviceSynchronize());  // part of the preparation, and its errors surface here
  return jump_clean;
}

void label_from_tree(const TreeView& tree, const std::uint8_t* jump_clean, const PaintGrids& grids, grid::Code first,
                     std::uint64_t count, std::int32_t* site, float* metres, std::uint8_t* boundary,
                     std::uint32_t* pending_spans, unsigned int* counters) {
  if (count == 0) {
    // nothing to label
  } else if (metres || count < kPaintMinCells) {
    // With distances the tree has no uniform leaves: cell by cell. So too for few cells, which
    // would give the paint kernel too few warps to hide its latency.
    tree_label_kernel<<<blocks_for(count), kBlock>>>(tree, first, count, site, metres, boundary);
    QTMV_CUDA_CHECK_LAUNCH("tree_label_kernel");
  } else {
    // Labels, flags 0 inside uniform leaves and pending elsewhere; then the pending flags.
    const std::uint64_t spans = (count + kPaintSpan - 1) / kPaintSpan;
    if (spans > 0xffffffffu - grids.paint_blocks * kPaintWarps) {
      throw std::invalid_argument("Labeller::run: too many cells for one launch");
    }
    QTMV_CUDA_CHECK(cudaMemsetAsync(counters, 0, 2 * sizeof(unsigned int)));
    const std::uint64_t blocks = (spans + kPaintWarps - 1) / kPaintWarps;
    tree_paint_kernel<<<static_cast<unsigned int>(blocks < grids.paint_blocks ? blocks : grids.paint_blocks), kBlock>>>(
        tree, jump_clean, first, count, site, boundary, boundary ? pending_spans : nullptr, counters, counters + 1);
    QTMV_CUDA_CHECK_LAUNCH("tree_paint_kernel");
    if (boundary) {
      // Enough blocks to fill the device; each takes listed spans in turn.
      tree_flag_kernel<<<grids.flag_blocks, kBlock>>>(tree, first, count, site, boundary, pending_spans, counters);
      QTMV_CUDA_CHECK_LAUNCH("tree_flag_kernel");
    }
  }
}

}  // namespace qtmv::label::cuda
