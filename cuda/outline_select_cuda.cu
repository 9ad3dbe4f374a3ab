// The outline selection's launches and copies (the device code: outline_select_kernels.cuh).
#include "outline_select_cuda.cuh"

#include <cub/device/device_scan.cuh>

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "common/parallel_copy.hpp"
#include "label_launch.cuh"
#include "outline_select_kernels.cuh"

namespace qtmv::label::cuda {

namespace {

/// Blocks of a grid-stride kernel over `segments`: enough to fill the device, not one a segment.
unsigned int grid_blocks(std::uint64_t segments) {
  return static_cast<unsigned int>(std::min<std::uint64_t>(segments, std::uint64_t{1} << 16));
}

}  // namespace

void OutlineSelection::allocate(std::uint64_t chunk, std::uint64_t tile_cells, std::size_t* bytes,
                                device_memory::FaultStep injected) {
  chunk_ = chunk;
  const std::uint64_t segments = (tile_cells + kSelectSegmentCells - 1) / kSelectSegmentCells;
  cells_ = device_memory::device_alloc<OutlineCell>(chunk, bytes, injected);
  per_segment_ = device_memory::device_alloc<std::uint64_t>(segments + 1, bytes, injected);
  offset_ = device_memory::device_alloc<std::uint64_t>(segments + 1, bytes, injected);
  std::size_t temp_bytes = 0;
  QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, temp_bytes, per_segment_.get(), offset_.get(),
                                                static_cast<std::int64_t>(segments + 1)));
  temp_ = device_memory::device_alloc<unsigned char>(temp_bytes, bytes, injected);
}

void OutlineSelection::select(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
                              const std::uint8_t* boundary, OutlineCells* out, std::uint64_t cells_left) {
  const std::uint64_t segments = (count + kSelectSegmentCells - 1) / kSelectSegmentCells;
  if (segments + 1 > offset_.size()) throw std::invalid_argument("OutlineSelection::select: a tile larger than allocated");
  count_outline_kernel<<<grid_blocks(segments), kBlock>>>(boundary, first, count, level, segments, per_segment_.get());
  QTMV_CUDA_CHECK_LAUNCH("count_outline_kernel");
  QTMV_CUDA_CHECK(cudaMemsetAsync(per_segment_.get() + segments, 0, sizeof(std::uint64_t)));
  std::size_t temp_bytes = temp_.size();
  QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp_.get(), temp_bytes, per_segment_.get(), offset_.get(),
                                                static_cast<std::int64_t>(segments + 1)));
  std::uint64_t total = 0;
  QTMV_CUDA_CHECK(cudaMemcpy(&total, offset_.get() + segments, sizeof total, cudaMemcpyDeviceToHost));
  if (total == 0) return;
  // Runs of segments whose outline cells fit the device buffer: all of them at once, unless the
  // tile has more outline cells than that (coarse levels with many sites).
  std::vector<std::uint64_t> cuts{0, segments};
  if (total > chunk_) {
    std::vector<std::uint64_t> offset(segments + 1);
    QTMV_CUDA_CHECK(cudaMemcpy(offset.data(), offset_.get(), offset.size() * sizeof(std::uint64_t), cudaMemcpyDeviceToHost));
    cuts.assign(1, 0);
    for (std::uint64_t s = 1; s <= segments; ++s) {
      // A segment holds at most kSelectSegmentCells <= chunk_ outline cells.
      if (offset[s] - offset[cuts.back()] > chunk_) cuts.push_back(s - 1);
    }
    cuts.push_back(segments);
  }
  const std::size_t at = out->size();
  grow_outline_cells(out, at + total + outline_room_for_rest(total, count, cells_left), host_threads(0));
  out->resize(at + total);
  OutlineCell* to = out->data() + at;
  try {
    write_runs(first, count, level, site, boundary, cuts, to);
  } catch (...) {
    out->resize(at);  // no cell of a tile left half copied
    throw;
  }
}

void OutlineSelection::write_runs(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
                                  const std::uint8_t* boundary, const std::vector<std::uint64_t>& cuts, OutlineCell* to) {
  for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
    const std::uint64_t from = cuts[k], to_segment = cuts[k + 1];
    write_outline_kernel<<<grid_blocks(to_segment - from), kBlock>>>(boundary, site, first, count, level, from, to_segment,
                                                                 offset_.get(), cells_.get());
    QTMV_CUDA_CHECK_LAUNCH("write_outline_kernel");
    std::uint64_t range[2] = {0, 0};
    QTMV_CUDA_CHECK(cudaMemcpy(&range[0], offset_.get() + from, sizeof(std::uint64_t), cudaMemcpyDeviceToHost));
    QTMV_CUDA_CHECK(cudaMemcpy(&range[1], offset_.get() + to_segment, sizeof(std::uint64_t), cudaMemcpyDeviceToHost));
    to = copy_to_host(range[1] - range[0], to);
  }
}

OutlineCell* OutlineSelection::copy_to_host(std::uint64_t cells, OutlineCell* to) {
  // Through page-locked memory in pieces, each copied on to the list on all cores (small
  // pageable copies, and the vector's growth, were most of the time) while the next piece
  // crosses into the buffer's other half.
  constexpr std::uint64_t kStagedCells = std::uint64_t{1} << 22;  // 48 MiB a half
  if (cells == 0) return to;
  const std::uint64_t staged = std::min(cells, kStagedCells);
  auto* host = static_cast<OutlineCell*>(host_.get(2 * staged * sizeof(OutlineCell)));
  for (cudaEvent_t& e : staging_.copied) {
    if (!e) QTMV_CUDA_CHECK(cudaEventCreateWithFlags(&e, cudaEventDisableTiming));
  }
  // Piece k goes to half k % 2, once the host has copied on the piece before it there.
  const auto start_copy = [&](std::uint64_t piece) {
    const std::uint64_t done = piece * staged, n = std::min(staged, cells - done);
    QTMV_CUDA_CHECK(cudaMemcpyAsync(host + (piece & 1) * staged, cells_.get() + done, n * sizeof(OutlineCell),
                                    cudaMemcpyDeviceToHost, nullptr));
    QTMV_CUDA_CHECK(cudaEventRecord(staging_.copied[piece & 1], nullptr));
  };
  const std::uint64_t pieces = (cells + staged - 1) / staged;
  start_copy(0);
  for (std::uint64_t piece = 0; piece < pieces; ++piece) {
    if (piece + 1 < pieces) start_copy(piece + 1);
    QTMV_CUDA_CHECK(cudaEventSynchronize(staging_.copied[piece & 1]));
    const std::uint64_t done = piece * staged;
    qtmv::parallel_copy(to + done, host + (piece & 1) * staged, std::min(staged, cells - done) * sizeof(OutlineCell),
                        host_threads(0));
  }
  return to + cells;
}

void OutlineSelection::free_device() {
  cells_.reset();
  per_segment_.reset();
  offset_.reset();
  temp_.reset();
}

}  // namespace qtmv::label::cuda
