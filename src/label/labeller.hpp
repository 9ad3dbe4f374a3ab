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

#include "common/run_context.hpp"
#include "grid/qtm.hpp"
#include "label/label_input.hpp"
#include "label/label_math.hpp"
#include "label/label_tree.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {

/// hier: the pruned tree; brute: every cell against every candidate (the seed paper's kernel);
/// automatic: brute on a GPU when cells x candidates is at most kBruteWorkLimit (the tree's
/// build then costs more than it saves), hier otherwise and on the CPU.
enum class Algorithm { hier, brute, automatic };

/// Cells x candidates up to which `automatic` takes brute force on a GPU (on an H200, 241 sites:
/// brute 0.67 ms against hier 0.12 ms + 0.9 ms of tree build at level 9, 2^21 cells).
constexpr double kBruteWorkLimit = 536870912.0;  // 2^29

struct LabelOptions {
  Rule rule = Rule::exact;
  Algorithm algorithm = Algorithm::automatic;
  std::string device = "auto";  ///< auto | cpu | cuda | cuda:N (common/device_spec.hpp)
  bool want_distance = true;    ///< fill LabelTile::distance_m
  bool want_boundary = true;    ///< fill LabelTile::boundary
  int threads = 0;              ///< CPU threads; 0: all (OpenMP's default)
  /// On a CUDA device, build `hier`'s tree on the device (the same tree as on the host, faster).
  bool tree_on_device = true;
  /// Memory (bytes) the dense outputs of one tile may take on the device that computes them
  /// (and on the host that receives them); 0: from the device's free memory / the host's RAM.
  std::size_t memory_limit_bytes = 0;
  /// The codes to label, both ends row starts (grid/qtm_code_ranges.hpp); an empty range (the
  /// default): the whole level. label_cells hands over the range's tiles; label_outlines gives
  /// the range's products (Outlines::range).
  grid::CodeRange range;
  /// Called with a fraction done (0..1) and the stage's name, between tiles and after each level
  /// of the tree build, on the calling thread; returning false stops the run with Interrupted.
  ProgressFunc progress;
  /// One-line messages for the user: which device was chosen, tiling (info), a GPU out of
  /// memory (warning).
  MessageSink messages;
};

/// A contiguous range of codes with its outputs (host memory, valid during the sink call).
struct LabelTile {
  grid::Code first = 0;
  std::uint64_t count = 0;
  const std::int32_t* site = nullptr;
  const float* distance_m = nullptr;     ///< metres; null when not asked for
  const std::uint8_t* boundary = nullptr;  ///< 0/1; null when not asked for
};

struct LabelStats {
  std::string device;          ///< "cpu (N threads)" or "cuda:N (name)"
  Algorithm algorithm = Algorithm::automatic;  ///< the one used (never automatic)
  double prepare_seconds = 0;  ///< pieces, tree (host wall time)
  double label_seconds = 0;    ///< the per-cell work: CUDA event time on a GPU, wall time on the CPU
  double copy_seconds = 0;     ///< device-to-host copies of the outputs
  double mean_candidates = 0;  ///< mean candidates tested per cell (own label only)
  std::size_t tree_nodes = 0;
  std::size_t tree_list_entries = 0;
  std::size_t device_bytes = 0;  ///< peak memory the labeller allocated on the device
  std::size_t tiles = 0;
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
