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

/// All cells' outputs in dense arrays indexed by code.
struct LabelResult {
  std::vector<std::int32_t> site;
  std::vector<float> distance_m;
  std::vector<std::uint8_t> boundary;
  LabelStats stats;
};
LabelResult label_all(const LabelInput& input, const LabelOptions& options);

// --- lower-level entry points, for the tests and the benchmark ----------------------------------

/// The input's fixed cells ordered by site, then in quadtree order (quadtree_key): into *storage,
/// unless they are in that order already (then the input's own array). make_candidates and the
/// device build take them in this order (the groups of a site's fixed cells are then compact
/// patches); labels and distances do not depend on it. `threads`: as LabelOptions::threads.
const FixedCell* fixed_cells_in_quadtree_order(const LabelInput& input, int threads, std::vector<FixedCell>* storage);

/// The exact rule's candidate of a site piece, and of a fixed cell (a fixed point piece at its
/// centre), on the host and on the device alike.
QTMV_HD inline Piece candidate_of(const SitePiece& p) {
  return p.a.x == p.b.x && p.a.y == p.b.y && p.a.z == p.b.z ? make_point_piece(p.a, p.site)
                                                             : make_arc_piece(p.a, p.b, p.site);
}
QTMV_HD inline Piece candidate_of(const FixedCell& f, int level) {
  return make_point_piece(grid::cell_centre_vector(f.code, level), f.site, kPieceFixed);
}

/// The candidates of a rule as kernel pieces (fixed cells become fixed point pieces at their
/// centres in both rules, after the other pieces, in fixed_cells_in_quadtree_order's order).
/// `threads`: as LabelOptions::threads.
std::vector<Piece> make_candidates(const LabelInput& input, Rule rule, int threads = 0);

/// The float64 brute-force label of one cell (the reference): best over all candidates.
Best reference_best(const std::vector<Piece>& candidates, grid::Code code, int level);

/// A leaf of the tree: its cell, level and node index (for painting its cells on the CPU).
struct TreeLeaf {
  grid::Cell cell;
  std::int32_t level;
  std::int32_t node;
};

/// The hierarchy, on the host. Leaves are kUniform (one site: no distances asked for, or all
/// cells fixed cells of the site) or list leaves (at the labelling level: the winner).
struct Tree {
  int level = 0;
  int jump_level = 0;
  std::vector<TreeNode> nodes;
  std::vector<std::int32_t> lists;
  std::vector<JumpEntry> jump;
  std::vector<TreeLeaf> leaves;
  std::vector<PieceGroup> groups;  ///< the line runs' groups that the lists' items refer to
  double mean_candidates = 0;  ///< candidates a cell of the level tests, on average
  TreeView view(const Piece* pieces) const {
    return {nodes.data(), lists.data(), pieces, groups.empty() ? nullptr : groups.data(), jump.data(), jump_level,
            level};
  }
};
/// Builds the pruned tree over `candidates` for `level`; with_distance keeps candidate lists
/// where all candidates share one site, so that distances can be computed.
/// `level_done` (may be empty) is called after each level of the tree with the fraction of the
/// levels done, outside any parallel region, so that it may throw to stop the build.
/// `fixed` (may be null): the fixed cells behind the candidates' fixed points; a node all of whose
/// cells are fixed cells of one site then becomes a uniform leaf even with distances (they are 0),
/// instead of the tree going on down inside polygons. The device build (cuda::Labeller, given the
/// same fixed cells) makes the same tree node for node: both apply decide_node (tree_node_rule.hpp).
Tree build_tree(const std::vector<Piece>& candidates, int level, bool with_distance, int threads = 0,
                const std::function<void(double fraction)>& level_done = {}, const FixedCell* fixed = nullptr,
                std::size_t fixed_count = 0);

/// Number of usable CUDA devices (0 when built without CUDA or none is present).
int cuda_device_count();

}  // namespace qtmv::label
