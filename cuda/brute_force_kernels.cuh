// Brute force's kernels: the paper's Kernel Function 1, every cell against every candidate, the
// candidates tiled through shared memory; the float64 maths of label_math.hpp, as the CPU's
// brute force (src/label/cpu_painter.cpp). Included by brute_force_cuda.cu alone, which launches
// them (so no relocatable device code).
#pragma once

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/label_math.hpp"
#include "label_launch.cuh"

namespace qtmv::label::cuda {

/// The best of all pieces for x, the pieces read through shared memory a block's tile at a time.
/// Every thread of the block must call it (it synchronises), active or not.
__device__ Best tiled_best(const Vec3& x, const Piece* pieces, int piece_count) {
  __shared__ Piece tile[kBlock];
  Best best = no_best();
  for (int base = 0; base < piece_count; base += kBlock) {
    const int n = piece_count - base < kBlock ? piece_count - base : kBlock;
    __syncthreads();
    if (static_cast<int>(threadIdx.x) < n) tile[threadIdx.x] = pieces[base + threadIdx.x];
    __syncthreads();
    consider_all(best, x, tile, n);
  }
  return best;
}

/// The labels (and distances when metres is not null) of codes [first, first + count).
__global__ void brute_label_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                   std::uint64_t count, std::int32_t* site, float* metres) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Best best = tiled_best(grid::cell_centre_vector(active ? first + k : first, level), pieces, piece_count);
  if (!active) return;
  site[k] = best.site;
  if (metres) metres[k] = static_cast<float>(chord2_to_metres(best.chord2));
}

/// Boundary flags from the labels of [first, first + count); neighbours outside the range are
/// labelled again by brute force (only the tile's edges).
__global__ void brute_boundary_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                      std::uint64_t count, const std::int32_t* site, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    grid::Cell nb[3];
    grid::neighbours(grid::cell_of(first + k, level), level, nb);
    std::uint8_t flag = 0;
    for (int s = 0; s < 3 && !flag; ++s) {
      const grid::Code code = grid::code_of(nb[s], level);
      std::int32_t other;
      if (code >= first && code - first < count) {
        other = site[code - first];
      } else {
        Best best = no_best();
        consider_all(best, grid::cell_centre_vector(code, level), pieces, piece_count);
        other = best.site;
      }
      flag = other != site[k];
    }
    boundary[k] = flag;
  }
}

/// The float64 brute-force label of each code of a list (the benchmark's reference).
__global__ void brute_codes_kernel(const Piece* pieces, int piece_count, int level, const grid::Code* codes,
                                   std::uint64_t count, std::int32_t* site) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Best best = tiled_best(grid::cell_centre_vector(active ? codes[k] : 0, level), pieces, piece_count);
  if (active) site[k] = best.site;
}

}  // namespace qtmv::label::cuda
