// The outline selection's device code: which cells of a labelled tile are outline cells
// (outline_cells.hpp: boundary cells and row ends), and their gathering. Included by
// outline_select_cuda.cu alone, which launches them (so no relocatable device code).
#pragma once

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label::cuda {

/// The outline selection's test of tile cell i (code first + i): a boundary cell or a row end.
struct OutlinePick {
  const std::uint8_t* boundary;
  grid::Code first;
  int level;
  __device__ bool operator()(std::uint32_t i) const {
    return boundary[i] != 0 || is_row_end(grid::cell_of(first + i, level));
  }
};

/// The selected cells (tile indices from `offset`) as outline cells.
__global__ void gather_outline_kernel(const std::uint32_t* index, std::uint32_t count, grid::Code first,
                                      const std::int32_t* site, const std::uint8_t* boundary, OutlineCell* out) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < count) {
    const std::uint32_t i = index[k];
    out[k] = OutlineCell(first + i, site[i], boundary[i] != 0);
  }
}

}  // namespace qtmv::label::cuda
