// The labeller's options as a caller gives them (the level's default, the distance rule, the
// algorithm, LabelOptions) and the statistics a run returns (LabelStats): plain data, below the
// labeller's API (labeller.hpp) and its stages (label_engine.hpp), which both include it, so that
// the readers' port and the pipeline's options take the enums without the labeller.
#pragma once

#include <cstddef>
#include <string>

#include "common/run_context.hpp"
#include "grid/qtm_code_ranges.hpp"

namespace qtmv::label {

/// The level a run labels when none is given: the seed paper's finest (2 million cells of about
/// 20 km).
constexpr int kDefaultLevel = 9;

/// The distance rule, from reading to labelling:
///   exact: distance from a cell's centre to the sites' geometry (points, and the short arcs
///          lines and rings are cut into); a site cell two sites pass through is kept by both,
///          and the distance decides;
///   cell:  the seed paper's rule: distance between cell centres, a site being the cells it
///          passes through; a cell two sites pass through goes to the lower site id.
enum class Rule { exact, cell };

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

/// What a run did: the device and algorithm used, its times (seconds) and sizes.
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

}  // namespace qtmv::label
