// The labeller: for every cell of a QTM level, the nearest site, the distance to it and
// whether the cell lies on a boundary between sites. Plain arrays in and out; no GDAL.
//
//   exact rule (default): nearest by great-circle distance from the cell's centre to the
//       sites' geometry: points, and the short great-circle arcs that lines and rings are cut
//       into; cells inside polygons ("fixed cells") keep their site at distance 0.
//   cell rule: the seed paper's rule: distance from the cell's centre to the centres of the
//       site cells (and fixed cells).
// Exact ties go to the lower site id. Both algorithms (brute force, hierarchical pruning) give
// the labels of a float64 brute-force reference on every cell, on the CPU and on CUDA alike.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "grid/qtm.hpp"
#include "label/label_input.hpp"
#include "label/label_options.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {

/// A contiguous range of codes with its outputs (host memory, valid during the sink call).
struct LabelTile {
  grid::Code first = 0;
  std::uint64_t count = 0;
  const std::int32_t* site = nullptr;
  const float* distance_m = nullptr;     ///< metres; null when not asked for
  const std::uint8_t* boundary = nullptr;  ///< 0/1; null when not asked for
};

/// Memory needed by the dense outputs of a level.
struct MemoryEstimate {
  std::uint64_t cells = 0;
  std::uint64_t output_bytes = 0;     ///< all cells' outputs
  std::uint64_t bytes_per_cell = 0;
};
MemoryEstimate estimate_output_memory(int level, const LabelOptions& options);

/// Labels every cell of input.level and hands the results to `sink` tile by tile, in code
/// order; tiles are as large as the memory allows. Throws std::invalid_argument for bad input,
/// std::runtime_error when the device is unusable or not even one tile fits (the message gives
/// the estimate).
LabelStats label_cells(const LabelInput& input, const LabelOptions& options,
                       const std::function<void(const LabelTile&)>& sink);

/// The outline cells and the cells per site of input.level (outline_cells.hpp), without every
/// cell's label on the host: on the CPU, `hier` visits only the list leaves and the rims of the
/// uniform leaves (work and memory follow the outlines); on a GPU the cells are labelled in
/// device tiles and their outline cells selected there, so only those cross to the host; the
/// CPU's brute force compacts its tiles as they come. Distances are not computed
/// (options.want_distance and want_boundary are ignored). Throws as label_cells.
LabelStats label_outlines(const LabelInput& input, const LabelOptions& options, Outlines* out);

/// All cells' outputs in dense arrays indexed by code.
struct LabelResult {
  std::vector<std::int32_t> site;
  std::vector<float> distance_m;
  std::vector<std::uint8_t> boundary;
  LabelStats stats;
};
/// Throws std::runtime_error when they would take more than half of this host's RAM.
LabelResult label_all(const LabelInput& input, const LabelOptions& options);
/// label_all without that check, for a caller that has weighed the memory itself (the pipeline).
LabelResult label_dense(const LabelInput& input, const LabelOptions& options);

/// Number of usable CUDA devices (0 when built without CUDA or none is present).
int cuda_device_count();

}  // namespace qtmv::label
