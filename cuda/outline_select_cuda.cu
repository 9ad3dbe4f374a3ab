// The outline selection's launches and copies (the device code: outline_select_kernels.cuh).
#include "outline_select_cuda.cuh"

#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <algorithm>
#include <cstring>
#include <thread>
#include <vector>

#include "label_launch.cuh"
#include "outline_select_kernels.cuh"

namespace qtmv::label::cuda {

namespace {

/// memcpy on several threads: the destination's first touch (page faults) and the copy of
/// gigabytes of outline cells, which one thread does at a few GB/s.
void parallel_copy(void* to, const void* from, std::size_t bytes) {
  constexpr std::size_t kPiece = std::size_t{16} << 20;
  const std::size_t pieces = (bytes + kPiece - 1) / kPiece;
  const std::size_t threads = std::min<std::size_t>(pieces, static_cast<std::size_t>(host_threads(0)));
  const auto work = [&](std::size_t t) {
    for (std::size_t k = t; k < pieces; k += threads) {
      const std::size_t first = k * kPiece;
      std::memcpy(static_cast<char*>(to) + first, static_cast<const char*>(from) + first,
                  std::min(kPiece, bytes - first));
    }
  };
  if (threads <= 1) {
    work(0);
    return;
  }
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& th : pool) th.join();
}

}  // namespace

void OutlineSelection::allocate(std::uint64_t chunk, const std::uint8_t* boundary, grid::Code first, int level,
                                std::size_t* bytes, device_memory::FaultStep injected) {
  chunk_ = chunk;
  index_ = device_memory::device_alloc<std::uint32_t>(chunk, bytes, injected);
  cells_ = device_memory::device_alloc<OutlineCell>(chunk, bytes, injected);
  count_ = device_memory::device_alloc<std::uint32_t>(1, bytes, injected);
  std::size_t temp_bytes = 0;
  QTMV_CUDA_CHECK(cub::DeviceSelect::If(nullptr, temp_bytes, thrust::counting_iterator<std::uint32_t>(0), index_.get(),
                                        count_.get(), static_cast<std::int64_t>(chunk),
                                        OutlinePick{boundary, first, level}));
  temp_ = device_memory::device_alloc<unsigned char>(temp_bytes, bytes, injected);
}

void OutlineSelection::select(grid::Code first, std::uint64_t count, int level, const std::int32_t* site,
                              const std::uint8_t* boundary, OutlineCells* out) {
  const std::uint64_t chunk = chunk_;
  // The chunks' outline cells gather in cells_ (a chunk's worth) and cross to the host in as few
  // copies as fit: small pageable copies, and the vector's growth, were most of the time.
  std::uint64_t pending = 0;
  const auto flush = [&](std::uint64_t done_cells) {
    if (pending == 0) return;
    const std::size_t at = out->size();
    if (out->capacity() < at + pending && done_cells < count) {
      // Room for the rest of the range at the rate seen so far, so that the vector grows once.
      const double rate = static_cast<double>(pending) / static_cast<double>(done_cells);
      out->reserve(at + static_cast<std::size_t>(pending + rate * 1.1 * static_cast<double>(count - done_cells)));
    }
    out->resize(at + pending);
    // Through page-locked memory in pieces, each copied on to the list on all cores.
    constexpr std::uint64_t kStagedCells = std::uint64_t{1} << 22;  // 64 MiB
    const std::uint64_t staged = std::min(pending, kStagedCells);
    auto* host = static_cast<OutlineCell*>(host_.get(staged * sizeof(OutlineCell)));
    for (std::uint64_t done = 0; done < pending; done += staged) {
      const std::uint64_t n = std::min(staged, pending - done);
      QTMV_CUDA_CHECK(cudaMemcpy(host, cells_.get() + done, n * sizeof(OutlineCell), cudaMemcpyDeviceToHost));
      parallel_copy(out->data() + at + done, host, n * sizeof(OutlineCell));
    }
    pending = 0;
  };
  for (std::uint64_t offset = 0; offset < count; offset += chunk) {
    const std::uint64_t n = std::min(chunk, count - offset);
    std::size_t temp_bytes = temp_.size();
    QTMV_CUDA_CHECK(cub::DeviceSelect::If(temp_.get(), temp_bytes, thrust::counting_iterator<std::uint32_t>(0),
                                          index_.get(), count_.get(), static_cast<std::int64_t>(n),
                                          OutlinePick{boundary + offset, first + offset, level}));
    std::uint32_t selected = 0;
    QTMV_CUDA_CHECK(cudaMemcpy(&selected, count_.get(), sizeof selected, cudaMemcpyDeviceToHost));
    if (selected == 0) continue;
    if (pending + selected > chunk) flush(offset);
    gather_outline_kernel<<<blocks_of(selected), kBlock>>>(index_.get(), selected, first + offset, site + offset,
                                                           boundary + offset, cells_.get() + pending);
    QTMV_CUDA_CHECK_LAUNCH("gather_outline_kernel");
    pending += selected;
  }
  flush(count);
}

void OutlineSelection::free_device() {
  index_.reset();
  cells_.reset();
  count_.reset();
  temp_.reset();
}

}  // namespace qtmv::label::cuda
