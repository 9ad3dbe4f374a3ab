// The candidates' launches (the kernels: candidates_kernels.cuh).
#include "candidates_cuda.cuh"

#include <cub/device/device_radix_sort.cuh>

#include <utility>
#include <vector>

#include "candidates_kernels.cuh"
#include "label/label_engine.hpp"
#include "label_launch.cuh"

namespace qtmv::label::cuda {

using device_memory::DeviceArray;
using device_memory::device_alloc;
using device_memory::FaultStep;

namespace {

/// The `n` (> 1) fixed cells of `level` in *fixed put in quadtree order here: keys, CUB's radix
/// sort, a gather (scratch bytes added to *scratch).
void order_fixed_cells(DeviceArray<FixedCell>* fixed, std::uint64_t n, int level, std::size_t* scratch,
                       FaultStep injected, DeviceTrace& trace) {
  const DeviceArray<unsigned long long> keys = device_alloc<unsigned long long>(2 * n, scratch, injected);
  const DeviceArray<std::uint32_t> index = device_alloc<std::uint32_t>(2 * n, scratch, injected);
  fixed_keys_kernel<<<blocks_for(n), kBlock>>>(fixed->get(), n, level, keys.get(), index.get());
  QTMV_CUDA_CHECK_LAUNCH("fixed_keys_kernel");
  std::size_t temp_bytes = 0;
  const int end_bit = 3 + 2 * level + 31;
  QTMV_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, keys.get(), keys.get() + n, index.get(),
                                                  index.get() + n, n, 0, end_bit));
  const DeviceArray<unsigned char> temp = device_alloc<unsigned char>(temp_bytes, scratch, injected);
  QTMV_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(temp.get(), temp_bytes, keys.get(), keys.get() + n, index.get(),
                                                  index.get() + n, n, 0, end_bit));
  DeviceArray<FixedCell> sorted = device_alloc<FixedCell>(n, scratch, injected);
  gather_fixed_kernel<<<blocks_for(n), kBlock>>>(fixed->get(), index.get() + n, n, sorted.get());
  QTMV_CUDA_CHECK_LAUNCH("gather_fixed_kernel");
  QTMV_CUDA_CHECK(cudaDeviceSynchronize());
  *fixed = std::move(sorted);
  trace("fixed cells in quadtree order", n);
}

}  // namespace

DeviceArray<Piece> make_device_pieces(const LabelInput& input, int threads, std::size_t* bytes, FaultStep injected,
                                      DeviceTrace& trace) {
  const std::size_t count = input.piece_count + input.fixed_cell_count;
  // The input goes over as it is (less to copy than the pieces) and becomes the pieces here, the
  // fixed cells in quadtree order (fixed_cells_in_quadtree_order, sorted here; on the host above
  // kMaxDeviceOrderLevel).
  std::vector<FixedCell> host_ordered;
  const FixedCell* fixed_input = input.fixed_cells;
  const bool order_here = input.level <= kMaxDeviceOrderLevel;
  if (!order_here) fixed_input = fixed_cells_in_quadtree_order(input, threads, &host_ordered);
  std::size_t scratch = 0;
  const DeviceArray<SitePiece> site_pieces = device_alloc<SitePiece>(input.piece_count, &scratch, injected);
  DeviceArray<FixedCell> fixed = device_alloc<FixedCell>(input.fixed_cell_count, &scratch, injected);
  if (input.piece_count) {
    QTMV_CUDA_CHECK(
        cudaMemcpy(site_pieces.get(), input.pieces, input.piece_count * sizeof(SitePiece), cudaMemcpyHostToDevice));
  }
  const std::uint64_t n = input.fixed_cell_count;
  if (n) {
    QTMV_CUDA_CHECK(cudaMemcpy(fixed.get(), fixed_input, n * sizeof(FixedCell), cudaMemcpyHostToDevice));
  }
  if (order_here && n > 1) order_fixed_cells(&fixed, n, input.level, &scratch, injected, trace);
  DeviceArray<Piece> pieces = device_alloc<Piece>(count, bytes, injected);
  make_pieces_kernel<<<blocks_for(count), kBlock>>>(site_pieces.get(), input.piece_count, fixed.get(),
                                                   input.fixed_cell_count, input.level, pieces.get());
  QTMV_CUDA_CHECK_LAUNCH("make_pieces_kernel");
  return pieces;  // the input's copies are freed here, before the build
}

}  // namespace qtmv::label::cuda
