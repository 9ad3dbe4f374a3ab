// The candidates' kernels: the exact rule's pieces made on the device from the labeller's input
// (candidate_of, as make_candidates in src/label/candidates.cpp), and the fixed cells put in
// quadtree order (fixed_cells_in_quadtree_order's order). Included by candidates_cuda.cu alone,
// which launches them (so no relocatable device code).
#pragma once

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/label_engine.hpp"
#include "label/label_input.hpp"
#include "label/label_math.hpp"

namespace qtmv::label::cuda {

/// The exact rule's candidates from the labeller's input, as make_candidates makes them.
__global__ void make_pieces_kernel(const SitePiece* site_pieces, std::uint64_t piece_count, const FixedCell* fixed,
                                   std::uint64_t fixed_count, int level, Piece* out) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < piece_count) {
    out[k] = candidate_of(site_pieces[k]);
  } else if (k < piece_count + fixed_count) {
    out[k] = candidate_of(fixed[k - piece_count], level);
  }
}

/// Levels up to which a fixed cell's sort key, site << (3 + 2 level) | quadtree_key, fits 64 bits.
constexpr int kMaxDeviceOrderLevel = 15;

/// fixed_cells_in_quadtree_order on the device: each cell's key (site, then quadtree order) and
/// its index, for a stable radix sort.
__global__ void fixed_keys_kernel(const FixedCell* fixed, std::uint64_t count, int level, unsigned long long* keys,
                                  std::uint32_t* index) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= count) return;
  const FixedCell f = fixed[k];
  keys[k] = (static_cast<unsigned long long>(f.site) << (3 + 2 * level)) |
            grid::quadtree_key(grid::cell_of(f.code, level), level);
  index[k] = static_cast<std::uint32_t>(k);
}

/// The fixed cells in their sorted order: out[k] = fixed[index[k]].
__global__ void gather_fixed_kernel(const FixedCell* fixed, const std::uint32_t* index, std::uint64_t count,
                                    FixedCell* out) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) out[k] = fixed[index[k]];
}

}  // namespace qtmv::label::cuda
