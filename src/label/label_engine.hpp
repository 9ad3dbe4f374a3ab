// The labeller's stages below label_cells, for its own files, the CUDA back end, the tests and
// the benchmark: candidates, the float64 reference, and the host's tree. A caller labelling a
// grid needs labeller.hpp only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "label/label_input.hpp"
#include "label/label_math.hpp"
#include "label/label_options.hpp"
#include "label/label_tree.hpp"
#include "label/outline_cells.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label {

/// The device a run labels on: options.device ("auto", "cpu", "cuda", "cuda:N") resolved against
/// the CUDA devices present. Throws std::runtime_error for a GPU asked for and missing.
struct DeviceChoice {
  bool cuda = false;
  int index = 0;  ///< the process's CUDA ordinal (cuda_device_name: the user's cuda:N)
};
DeviceChoice choose_device(const std::string& name);
/// Every device a name asks for ("cuda:all": all CUDA devices; "cuda:0,2": those two; the other
/// forms: one); the first is choose_device's. Throws as choose_device.
std::vector<DeviceChoice> choose_devices(const std::string& name);

/// label_outlines on several devices at once, named as LabelOptions::device ("cpu", "cuda:1"): the
/// range is split in rows (grid::split_in_rows) into one part per name, each labelled on its
/// own thread, and the parts' products joined. Progress is reported, and a stop honoured, on the
/// calling thread. The products are those of one device. (label_outlines calls it for several
/// GPUs; the tests give it several "cpu".)
LabelStats label_outlines_on(const LabelInput& input, const LabelOptions& options,
                             const std::vector<std::string>& devices, Outlines* out);

/// The input checks of label_cells: throws std::invalid_argument naming the first bad entry.
void check_label_input(const LabelInput& input, Rule rule);

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

/// The candidates of a rule as kernel pieces (fixed cells, and the cells of fixed nodes, become
/// fixed point pieces at their centres in both rules, after the other pieces, in
/// fixed_cells_in_quadtree_order's order): with fixed nodes, the float64 reference's candidates;
/// the tree is given the input's fixed cells and only the cover of its coarse nodes.
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
/// cells fixed cells of the site) or list leaves (at the labelling level: the winner). The arrays
/// are filled on all cores as they grow, so they are not zeroed first (DefaultInitVector: on
/// one core, the zeroing took longer than the build's filtering at 135 000 points).
struct Tree {
  int level = 0;
  int jump_level = 0;
  DefaultInitVector<TreeNode> nodes;
  DefaultInitVector<std::int32_t> lists;
  DefaultInitVector<JumpEntry> jump;
  DefaultInitVector<TreeLeaf> leaves;
  std::vector<PieceGroup> groups;  ///< the line runs' groups that the lists' items refer to
  double mean_candidates = 0;  ///< candidates a cell of the level tests, on average
  /// The codes the tree labels (build_tree's `focus`); empty (end 0): every cell of the level.
  grid::CodeRange focus;
  /// How many cells the tree labels: its focus's, or the level's.
  std::uint64_t labelled_cells() const { return focus.end != 0 ? focus.size() : grid::cell_count(level); }
  TreeView view(const Piece* pieces) const {
    return {nodes.data(), lists.data(), pieces, groups.empty() ? nullptr : groups.data(), jump.data(), jump_level,
            level};
  }
};
/// The jump table's level: full (tree_jump_level: every cell's walk, the dense paths) or outline
/// (tree_outline_jump_level: the outline pass's few look-ups); fill_jump_table changes it.
enum class JumpTable { full, outline };

/// Builds the pruned tree over `candidates` for `level`; with_distance keeps candidate lists
/// where all candidates share one site, so that distances can be computed.
/// `level_done` (may be empty) is called after each level of the tree with the fraction of the
/// levels done, outside any parallel region, so that it may throw to stop the build.
/// `cover` (may be null): the cells that fixed cells and fixed nodes claim (fixed_cover.hpp); a
/// node all of whose cells one site claims then becomes a uniform leaf even with distances (they
/// are 0), instead of the tree going on down inside polygons, and a node partly claimed above
/// the list level is split. The candidates must hold the fixed points of every claimed cell that
/// does not lie in a node of level <= tree_list_level(level) of the cover. The device build
/// (cuda::Labeller, given the same cover) makes the same tree node for node: both apply
/// decide_node (tree_node_rule.hpp).
/// `jump`: the jump table's level (JumpTable).
/// `focus` (empty, end 0: the whole level): the codes that will be labelled, a tile job's range.
/// Only the nodes whose rows meet it (grid::rows_meet) or that lie next to such a node are built;
/// every other node is a uniform leaf of an arbitrary site at once. The cells of the focus and
/// their edge neighbours (for the boundary flags) then get the whole tree's labels: a cell's
/// ancestor at each level meets the focus, and its neighbour's is that node or one across an
/// edge of it. A tile of 1/N of the level costs about 1/N of the whole build.
Tree build_tree(const std::vector<Piece>& candidates, int level, bool with_distance, int threads = 0,
                const std::function<void(double fraction)>& level_done = {}, const CoverView* cover = nullptr,
                JumpTable jump = JumpTable::full, grid::CodeRange focus = {});

/// Makes `tree`'s jump table the one of `jump_level` (nothing to do when it is already).
void fill_jump_table(Tree& tree, int jump_level, int threads = 0);
/// The jump table of `jump_level` for the tree of `nodes`: per cell of that level, where its walk starts.
DefaultInitVector<JumpEntry> make_jump_table(const TreeNode* nodes, int jump_level, int threads = 0);

}  // namespace qtmv::label
