// Brute force's launches (the kernels: brute_force_kernels.cuh).
#include "brute_force_cuda.cuh"

#include "brute_force_kernels.cuh"
#include "label_launch.cuh"

namespace qtmv::label::cuda {

using device_memory::DeviceArray;

void label_by_brute_force(const Piece* pieces, int piece_count, int level, grid::Code first, std::uint64_t count,
                          std::int32_t* site, float* metres, std::uint8_t* boundary) {
  brute_label_kernel<<<blocks_for(count), kBlock>>>(pieces, piece_count, level, first, count, site, metres);
  QTMV_CUDA_CHECK_LAUNCH("brute_label_kernel");
  if (boundary) {
    brute_boundary_kernel<<<blocks_for(count), kBlock>>>(pieces, piece_count, level, first, count, site, boundary);
    QTMV_CUDA_CHECK_LAUNCH("brute_boundary_kernel");
  }
}

std::vector<std::int32_t> brute_force_sites(const Piece* pieces, int piece_count, int level,
                                            const std::vector<grid::Code>& codes, device_memory::FaultStep injected) {
  std::size_t scratch = 0;
  DeviceArray<grid::Code> device_codes = device_memory::device_copy(codes, &scratch, injected);
  DeviceArray<std::int32_t> device_sites = device_memory::device_alloc<std::int32_t>(codes.size(), &scratch, injected);
  std::vector<std::int32_t> sites(codes.size());
  if (!codes.empty()) {
    brute_codes_kernel<<<blocks_for(codes.size()), kBlock>>>(pieces, piece_count, level, device_codes.get(),
                                                             codes.size(), device_sites.get());
    QTMV_CUDA_CHECK_LAUNCH("brute_codes_kernel");
    QTMV_CUDA_CHECK(
        cudaMemcpy(sites.data(), device_sites.get(), codes.size() * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  device_codes.free_checked();
  device_sites.free_checked();
  return sites;
}

}  // namespace qtmv::label::cuda
