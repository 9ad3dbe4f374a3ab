// The input's fixed cells and fixed nodes (label_input.hpp) as the labeller uses them: the cover
// that both tree builds look nodes up in, and the fixed cells that become candidate points.
#pragma once

#include <cstdint>
#include <vector>

#include "label/label_input.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label {

/// The cells that the input's fixed cells and fixed nodes claim, as CoverView's key ranges.
struct FixedCover {
  int level = 0;
  std::vector<std::uint64_t> first, last;
  std::vector<std::int32_t> site, owner_run;
  bool split_partly = false;  ///< as CoverView's
  bool empty() const { return site.empty(); }
  CoverView view() const {
    return {first.data(), last.data(), site.data(), owner_run.data(), site.size(), level, split_partly};
  }
};

/// The cover of all of the input's fixed cells and fixed nodes (held_claims, label_input.hpp).
FixedCover make_fixed_cover(const LabelInput& input);

/// The input's fixed cells, then every cell of its fixed nodes (code order within a node): all
/// the cells that the input claims, cell by cell.
std::vector<FixedCell> fixed_cells_with_nodes(const LabelInput& input);

/// The input as a labelling takes it. For the tree (`hier`): the cover of its claims; with fixed
/// nodes, no fixed cells at all (claims have no candidate points; the tree splits partly claimed
/// nodes down to the level, CoverView::split_partly, so every claimed cell lies in a covered
/// leaf), without them the input's fixed cells as fixed points. For brute force: every claimed
/// cell as a fixed cell (no cover). `input` points into this object's arrays or the caller's.
struct PreparedInput {
  LabelInput input;
  FixedCover cover;
  std::vector<FixedCell> fixed_cells;
};
PreparedInput prepare_input(const LabelInput& given, bool hier);

/// Number of cells below the input's fixed nodes.
std::uint64_t fixed_node_cells(const LabelInput& input);

}  // namespace qtmv::label
