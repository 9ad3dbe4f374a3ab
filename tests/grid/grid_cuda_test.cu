// The grid on a CUDA device: the same per-cell checks as the CPU sweep, and every cell of
// level 10 must give the CPU's code, centre and neighbours bit for bit.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <cstring>
#include <vector>

#include "grid/qtm.hpp"
#include "grid_cell_checks.hpp"

namespace qtmv::grid {
namespace {

using test::CellRecord;

#define ASSERT_CUDA(call)                                                                             \
  do {                                                                                                \
    const cudaError_t status_ = (call);                                                               \
    ASSERT_EQ(status_, cudaSuccess) << #call << ": " << cudaGetErrorString(status_);                  \
  } while (0)

constexpr int kComparedLevel = 10;
constexpr Code kChunkCells = Code{1} << 20;

__global__ void check_cells_kernel(Code first, Code count, int level, unsigned long long* failures,
                                   unsigned* any_bits, CellRecord* records) {
  const Code offset = blockIdx.x * static_cast<Code>(blockDim.x) + threadIdx.x;
  if (offset >= count) return;
  const Code code = first + offset;
  const unsigned bits = test::check_cell(code, level);
  if (bits != 0) {
    atomicAdd(failures, 1ull);
    atomicOr(any_bits, bits);
  }
  if (records != nullptr) records[offset] = test::make_cell_record(code, level);
}

bool have_gpu() {
  int devices = 0;
  return cudaGetDeviceCount(&devices) == cudaSuccess && devices > 0;
}

TEST(GridCuda, CellChecksPassOnDeviceAndMatchCpuAtLevel10) {
  if (!have_gpu()) GTEST_SKIP() << "no CUDA device";
  unsigned long long* d_failures = nullptr;
  unsigned* d_bits = nullptr;
  CellRecord* d_records = nullptr;
  ASSERT_CUDA(cudaMalloc(&d_failures, sizeof *d_failures));
  ASSERT_CUDA(cudaMalloc(&d_bits, sizeof *d_bits));
  ASSERT_CUDA(cudaMalloc(&d_records, kChunkCells * sizeof(CellRecord)));
  ASSERT_CUDA(cudaMemset(d_failures, 0, sizeof *d_failures));
  ASSERT_CUDA(cudaMemset(d_bits, 0, sizeof *d_bits));

  std::vector<CellRecord> gpu(kChunkCells);
  std::uint64_t mismatches = 0;
  Code first_mismatch = kInvalidCode;
  const Code total = cell_count(kComparedLevel);
  for (Code first = 0; first < total; first += kChunkCells) {
    const Code count = std::min(kChunkCells, total - first);
    // Poison, so an unwritten record cannot pass.
    ASSERT_CUDA(cudaMemset(d_records, 0xff, count * sizeof(CellRecord)));
    const unsigned threads = 256;
    check_cells_kernel<<<static_cast<unsigned>((count + threads - 1) / threads), threads>>>(
        first, count, kComparedLevel, d_failures, d_bits, d_records);
    ASSERT_CUDA(cudaGetLastError());
    ASSERT_CUDA(cudaMemcpy(gpu.data(), d_records, count * sizeof(CellRecord), cudaMemcpyDeviceToHost));
    for (Code k = 0; k < count; ++k) {
      const CellRecord cpu = test::make_cell_record(first + k, kComparedLevel);
      if (std::memcmp(&cpu, &gpu[k], sizeof cpu) != 0 && mismatches++ == 0) first_mismatch = first + k;
    }
  }
  unsigned long long failures = 0;
  unsigned bits = 0;
  ASSERT_CUDA(cudaMemcpy(&failures, d_failures, sizeof failures, cudaMemcpyDeviceToHost));
  ASSERT_CUDA(cudaMemcpy(&bits, d_bits, sizeof bits, cudaMemcpyDeviceToHost));
  ASSERT_CUDA(cudaFree(d_records));
  ASSERT_CUDA(cudaFree(d_bits));
  ASSERT_CUDA(cudaFree(d_failures));
  EXPECT_EQ(failures, 0u) << "failure bits " << bits;
  EXPECT_EQ(mismatches, 0u) << "first cell where CPU and GPU differ: " << first_mismatch;
  std::printf("[   INFO   ] level %d: %llu cells checked on the GPU, %llu CPU/GPU mismatches\n", kComparedLevel,
              static_cast<unsigned long long>(total), static_cast<unsigned long long>(mismatches));
}

TEST(GridCuda, DeviceSweepLevels0To8) {
  if (!have_gpu()) GTEST_SKIP() << "no CUDA device";
  unsigned long long* d_failures = nullptr;
  unsigned* d_bits = nullptr;
  ASSERT_CUDA(cudaMalloc(&d_failures, sizeof *d_failures));
  ASSERT_CUDA(cudaMalloc(&d_bits, sizeof *d_bits));
  for (int level = 0; level <= 8; ++level) {
    ASSERT_CUDA(cudaMemset(d_failures, 0, sizeof *d_failures));
    const Code count = cell_count(level);
    check_cells_kernel<<<static_cast<unsigned>((count + 255) / 256), 256>>>(0, count, level, d_failures, d_bits,
                                                                          nullptr);
    ASSERT_CUDA(cudaGetLastError());
    unsigned long long failures = 0;
    ASSERT_CUDA(cudaMemcpy(&failures, d_failures, sizeof failures, cudaMemcpyDeviceToHost));
    EXPECT_EQ(failures, 0u) << "level " << level;
  }
  ASSERT_CUDA(cudaFree(d_bits));
  ASSERT_CUDA(cudaFree(d_failures));
}

}  // namespace
}  // namespace qtmv::grid
