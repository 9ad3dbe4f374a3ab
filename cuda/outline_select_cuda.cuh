// The outline selection on the device (outline_select_cuda.cu): a labelled tile's outline cells
// (outline_cells.hpp), counted per segment of cells, written in runs of segments that fit the
// device buffer and copied to the host, for Labeller::select_outline.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "device_memory.cuh"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"
#include "label_launch.cuh"

namespace qtmv::label::cuda {

/// Cells a thread of the selection reads at once (one 16-byte load of flags).
constexpr int kSelectCellsPerThread = 16;
/// Cells of a segment: one block's, the unit of the counts and offsets.
constexpr std::uint64_t kSelectSegmentCells = std::uint64_t{kBlock} * kSelectCellsPerThread;

/// select_outline's buffers: up to `chunk` outline cells, the segments' counts and their
/// exclusive sum, CUB's scratch on the device, and the outline cells' page-locked way to the host.
class OutlineSelection {
 public:
  /// Whether the device buffers are there (allocate since the last free_device).
  bool allocated() const { return static_cast<bool>(cells_); }
  /// The device buffers for `chunk` outline cells at a time (at least kSelectSegmentCells) of
  /// tiles of up to `tile_cells` cells; their bytes added to *bytes.
  void allocate(std::uint64_t chunk, std::uint64_t tile_cells, std::size_t* bytes, device_memory::FaultStep injected);
  /// Appends the outline cells of the tile's cells [0, count) (codes first.., labels `site`,
  /// flags `boundary`) to *out, in code order; *out grows with room for `cells_left` more cells
  /// at this tile's rate (Labeller::select_outline).
  void select(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
              const std::uint8_t* boundary, OutlineCells* out, std::uint64_t cells_left);
  /// Frees the device buffers (the page-locked buffer stays, for the next tiles).
  void free_device();

 private:
  /// Writes the outline cells of the runs of segments [cuts[k], cuts[k + 1]) to the host from `to` on.
  void write_runs(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
                  const std::uint8_t* boundary, const std::vector<std::uint64_t>& cuts, OutlineCell* to);
  /// Copies the first `cells` outline cells of the device buffer to `to`; returns to + cells.
  OutlineCell* copy_to_host(std::uint64_t cells, OutlineCell* to);

  /// The two halves of the page-locked buffer and the events of their copies from the device.
  struct Staging {
    cudaEvent_t copied[2] = {nullptr, nullptr};
    Staging() = default;
    Staging(const Staging&) = delete;
    Staging& operator=(const Staging&) = delete;
    ~Staging() {
      for (cudaEvent_t e : copied) {
        if (e) (void)cudaEventDestroy(e);
      }
    }
  };

  std::uint64_t chunk_ = 0;
  device_memory::DeviceArray<OutlineCell> cells_;
  device_memory::DeviceArray<std::uint64_t> per_segment_;
  device_memory::DeviceArray<std::uint64_t> offset_;
  device_memory::DeviceArray<unsigned char> temp_;
  device_memory::PinnedBuffer host_;
  Staging staging_;
};

}  // namespace qtmv::label::cuda
