// The pruned hierarchy that the `hier` algorithm builds, and the per-cell look-up in it, one
// body for the CPU and the CUDA kernels (QTMV_HD).
//
// The tree follows the QTM quadtrees: node indices 0..7 are the octants (level 0), and an
// internal node's four children are stored at consecutive indices in the order of
// grid::children(). Each node kept the candidates (items: pieces, or groups of a line run,
// piece_groups.hpp) that can be nearest to some point of it (label_math.hpp: prune_threshold, and
// for point items point_never_nearest with the node's nearest point item, which tells apart a
// tight cluster's points far from it and drops the duplicates of sites at one point);
// a node stops being split when
//   - all its candidates belong to one site and no distances are asked for, or all its cells
//     are fixed cells of one site (kUniform), or
//   - it is at the labelling level, or its candidate list is short enough that the cells
//     below it may as well test it directly (a "list leaf").
// A cell's label is then: walk from the root (or from the jump table) to the leaf holding it
// and, for a list leaf, take the best of the leaf's few candidates.
#pragma once

#include <cstdint>

#include "grid/qtm_hierarchy.hpp"
#include "label/label_math.hpp"
#include "label/piece_groups.hpp"

namespace qtmv::label {

/// Values of TreeNode::count below zero.
enum TreeNodeKind : std::int32_t {
  kInternal = -1,  ///< value: index of the first of the four children
  kUniform = -2,   ///< value: the site of every cell below
};

/// Levels above the labelling level at which mixed nodes stop being split (see build_tree).
constexpr int kListDepth = 3;
/// A mixed node with more candidates than this goes on being split (down to the level, where
/// each cell's winner is settled in the build): dense line sites keep the lists short.
constexpr std::uint32_t kMaxLeafList = 64;

/// The level at which mixed nodes become list leaves, and the level of the jump table.
QTMV_HD inline int tree_list_level(int level) { return level - kListDepth > 0 ? level - kListDepth : 0; }
QTMV_HD inline int tree_jump_level(int level) {
  // The list leaves' level (most walks from the table end at once), at most 11:
  // 8 * 4^11 entries (256 MiB).
  const int j = level - kListDepth < 11 ? level - kListDepth : 11;
  return j > 0 ? j : 0;
}
/// Levels the outline pass's jump table lies above tree_jump_level. The pass only looks up the
/// leaves of cells along the outlines, where a few more levels of walk cost less than a table
/// whose entries follow the cells (4^4 = 256 times fewer: 8192 instead of 2 million at level 12).
constexpr int kOutlineJumpRise = 4;
/// The level of the jump table for the outline pass (cpu_tree_outlines).
QTMV_HD inline int tree_outline_jump_level(int level) {
  const int j = tree_jump_level(level) - kOutlineJumpRise;
  return j > 0 ? j : 0;
}

/// One node: kind (count < 0) or the length of its candidate list (count >= 1, value: offset of
/// the list in TreeView::lists).
struct TreeNode {
  std::int32_t count;
  std::int32_t value;
};

/// Where the walk of a cell of the jump level starts: a node and its level.
struct JumpEntry {
  std::int32_t node;
  std::int32_t level;
};

/// The tree as plain pointers, valid on the side (host or device) that owns them.
struct TreeView {
  const TreeNode* nodes;
  const std::int32_t* lists;   ///< candidate lists of the list leaves (items: piece_groups.hpp)
  const Piece* pieces;
  const PieceGroup* groups;    ///< the line runs' groups (null when there are none)
  const JumpEntry* jump;        ///< per cell of jump_level: the node to start the walk from
  int jump_level;
  int level;                   ///< the labelling level L
};

/// Index of the leaf that holds cell c (of the labelling level); its level in *leaf_level.
QTMV_HD inline std::int32_t find_leaf(const TreeView& t, const grid::Cell& c, int* leaf_level) {
  const grid::Cell start = grid::ancestor(c, t.level, t.jump_level);
  const JumpEntry jump = t.jump[grid::code_of(start, t.jump_level)];
  std::int32_t node = jump.node;
  int level = jump.level;
  TreeNode n = t.nodes[node];
  while (n.count == kInternal) {
    node = n.value + grid::child_digit(grid::ancestor(c, t.level, level + 1));
    n = t.nodes[node];
    ++level;
  }
  *leaf_level = level;
  return node;
}

/// The walk that builds the jump table: from the octant's root down to jump_level or a leaf.
QTMV_HD inline JumpEntry walk_to_jump_level(const TreeNode* nodes, const grid::Cell& c, int jump_level) {
  std::int32_t node = c.octant;
  int level = 0;
  for (; level < jump_level && nodes[node].count == kInternal; ++level) {
    node = nodes[node].value + grid::child_digit(grid::ancestor(c, jump_level, level + 1));
  }
  return {node, level};
}

/// True when jump cell `jump_code` lies in a uniform leaf and so do its three edge neighbours (of
/// the jump level), all with one site: then no cell below it is a boundary cell, since a cell's
/// edge neighbours lie in its own jump cell or in the one across that edge.
QTMV_HD inline bool jump_cell_clean(const TreeView& t, grid::Code jump_code) {
  const TreeNode own = t.nodes[t.jump[jump_code].node];
  if (own.count != kUniform) return false;
  grid::Code nb[3];
  grid::neighbours(grid::cell_of(jump_code, t.jump_level), jump_code, t.jump_level, nb);
  for (const grid::Code n : nb) {
    const TreeNode other = t.nodes[t.jump[n].node];
    if (other.count != kUniform || other.value != own.value) return false;
  }
  return true;
}

/// A boundary flag not settled yet: a neighbour lies in a list leaf, whose label is needed.
constexpr std::uint8_t kBoundaryPending = 2;

/// The best candidate of a list leaf for the point x (unit vector).
QTMV_HD inline Best best_of_list(const TreeView& t, const TreeNode& leaf, const Vec3& x) {
  return best_of_items(x, t.lists + leaf.value, leaf.count, t.pieces, t.groups, nullptr);
}

/// The site of cell c (of the labelling level).
QTMV_HD inline std::int32_t tree_label(const TreeView& t, const grid::Cell& c) {
  int leaf_level;
  const TreeNode leaf = t.nodes[find_leaf(t, c, &leaf_level)];
  if (leaf.count == kUniform) return leaf.value;
  return best_of_list(t, leaf, grid::cell_centre_vector(c, t.level)).site;
}

/// The boundary flag (0/1) of cell c (of the labelling level), whose site is `site` and whose
/// leaf (find_leaf) is node `leaf_index` of level `leaf_level`: 1 when one of its three edge
/// neighbours has another site, looked up in the tree.
QTMV_HD inline std::uint8_t tree_boundary_flag(const TreeView& t, const grid::Cell& c, std::int32_t leaf_index,
                                               int leaf_level, std::int32_t site) {
  const TreeNode leaf = t.nodes[leaf_index];
  if (leaf.count == kUniform && grid::interior_of_ancestor(c, t.level, leaf_level)) return 0;
  grid::Cell nb[3];
  grid::neighbours(c, t.level, nb);
  for (int k = 0; k < 3; ++k) {
    int other_level;
    const std::int32_t other_leaf = find_leaf(t, nb[k], &other_level);
    // Cells of one uniform leaf share its site.
    if (other_leaf == leaf_index && leaf.count == kUniform) continue;
    const TreeNode other = t.nodes[other_leaf];
    std::int32_t other_site;
    if (other.count == kUniform) {
      other_site = other.value;
    } else {
      other_site = best_of_list(t, other, grid::cell_centre_vector(nb[k], t.level)).site;
    }
    if (other_site != site) return 1;
  }
  return 0;
}

/// Label, optional distance and optional boundary flag of one cell. A cell is a boundary cell
/// when one of its three edge neighbours has another site; the neighbours' labels are looked
/// up in the tree, so this needs no label array and works on any range of codes.
/// *candidates_out (when not null) gets the number of candidates tested for the cell's own label.
QTMV_HD inline void tree_label_cell(const TreeView& t, grid::Code code, std::int32_t* site_out, float* metres_out,
                                    std::uint8_t* boundary_out) {
  const grid::Cell c = grid::cell_of(code, t.level);
  int leaf_level;
  const std::int32_t leaf_index = find_leaf(t, c, &leaf_level);
  const TreeNode leaf = t.nodes[leaf_index];
  std::int32_t site;
  if (leaf.count == kUniform) {
    site = leaf.value;
    // A tree built with distances has uniform leaves only where every cell is a fixed cell of
    // the site (build_tree's `fixed`): distance 0.
    if (metres_out) *metres_out = 0.0f;
  } else {
    const Best best = best_of_list(t, leaf, grid::cell_centre_vector(c, t.level));
    site = best.site;
    if (metres_out) *metres_out = static_cast<float>(chord2_to_metres(best.chord2));
  }
  *site_out = site;
  if (boundary_out) *boundary_out = tree_boundary_flag(t, c, leaf_index, leaf_level, site);
}

}  // namespace qtmv::label
