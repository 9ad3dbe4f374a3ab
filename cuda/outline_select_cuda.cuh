// The outline selection on the device (outline_select_cuda.cu): a labelled tile's outline cells
// (outline_cells.hpp), selected in chunks with CUB and copied to the host, for
// Labeller::select_outline.
#pragma once

#include <cstddef>
#include <cstdint>

#include "device_memory.cuh"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label::cuda {

/// select_outline's buffers: a chunk's selected indices, their outline cells, the count, CUB's
/// scratch on the device, and the outline cells' page-locked way to the host.
class OutlineSelection {
 public:
  /// Whether the device buffers are there (allocate since the last free_device).
  bool allocated() const { return static_cast<bool>(index_); }
  /// The device buffers for chunks of `chunk` cells of a tile whose flags are `boundary`; their
  /// bytes added to *bytes.
  void allocate(std::uint64_t chunk, const std::uint8_t* boundary, grid::Code first, int level, std::size_t* bytes,
                device_memory::FaultStep injected);
  /// Appends the outline cells of the tile's cells [0, count) (codes first.., labels `site`,
  /// flags `boundary`) to *out, a chunk at a time.
  void select(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
              const std::uint8_t* boundary, OutlineCells* out);
  /// Frees the device buffers (the page-locked buffer stays, for the next tiles).
  void free_device();

 private:
  std::uint64_t chunk_ = 0;
  device_memory::DeviceArray<std::uint32_t> index_;
  device_memory::DeviceArray<OutlineCell> cells_;
  device_memory::DeviceArray<std::uint32_t> count_;
  device_memory::DeviceArray<unsigned char> temp_;
  device_memory::PinnedBuffer host_;
};

}  // namespace qtmv::label::cuda
