// The pruned hierarchy that the `hier` algorithm builds, and the per-cell look-up in it, one
// body for the CPU and the CUDA kernels (QTMV_HD).
//
// The tree follows the QTM quadtrees: node indices 0..7 are the octants (level 0), and an
// internal node's four children are stored at consecutive indices in the order of
// grid::children(). Each node kept the candidates (items: pieces, or groups of a line run,
// piece_groups.hpp) that can be nearest to some point of it (label_math.hpp, prune_threshold);
// a node stops being split when
//   - all its candidates belong to one site and no distances are asked for, or all its cells
//     are fixed cells of one site (kUniform), or
//   - it is at the labelling level, or its candidate list is short enough that the cells
//     below it may as well test it directly (a "list leaf").
// A cell's label is then: walk from the root (or from the jump table) to the leaf holding it
// and, for a list leaf, take the best of the leaf's few candidates.
#pragma once

#include <cstdint>

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

/// ancestor()'s column, k levels up, of the cell in column `col` of local row `local_row`: the
/// paint kernel uses it alone for the cells of one row.
QTMV_HD inline std::uint32_t ancestor_col(std::uint32_t col, std::uint32_t local_row, int k) {
  return ((col >> (k + 1)) << 1) | ((col & ((2u << k) - 1u)) > 2 * local_row ? 1u : 0u);
}

/// The ancestor at level `to` (<= from) of cell c of level `from`. Row r of an ancestor k = from - to
/// levels up holds rows r 2^k .. r 2^k + 2^k - 1 below it; in the local row lr of those, the up
/// ancestor (column 2a) holds columns a 2^(k+1) .. a 2^(k+1) + 2 lr and the down ancestor (column
/// 2a + 1) the rest of the block of 2^(k+1) columns. Shifts and masks only (the tests compare it
/// with grid::parent applied k times).
QTMV_HD inline grid::Cell ancestor(const grid::Cell& c, int from, int to) {
  const int k = from - to;
  return {c.octant, c.row >> k, ancestor_col(c.col, c.row & ((1u << k) - 1u), k)};
}

/// Position (0..3) of cell c among its parent's children, in grid::children() order.
QTMV_HD inline int child_digit(const grid::Cell& c) {
  const std::uint32_t m = c.col & 3u;
  if ((c.row & 1u) == 0) return m == 0 ? 0 : static_cast<int>(m) - 1;
  return m == 3 ? 3 : static_cast<int>(m) + 1;
}

/// Position of cell c (of `level`) in quadtree order: the octant, then the child digits from
/// level 1 down, 2 bits each (3 + 2 level bits). The cells below any node have consecutive keys,
/// those of node a (level l) being [key(a) << 2 (level - l), (key(a) + 1) << 2 (level - l)).
QTMV_HD inline std::uint64_t quadtree_key(const grid::Cell& c, int level) {
  std::uint64_t key = static_cast<std::uint64_t>(c.octant);
  for (int l = 1; l <= level; ++l) key = (key << 2) | static_cast<std::uint64_t>(child_digit(ancestor(c, level, l)));
  return key;
}

/// Index of the leaf that holds cell c (of the labelling level); its level in *leaf_level.
QTMV_HD inline std::int32_t find_leaf(const TreeView& t, const grid::Cell& c, int* leaf_level) {
  const grid::Cell start = ancestor(c, t.level, t.jump_level);
  const JumpEntry jump = t.jump[grid::code_of(start, t.jump_level)];
  std::int32_t node = jump.node;
  int level = jump.level;
  TreeNode n = t.nodes[node];
  while (n.count == kInternal) {
    node = n.value + child_digit(ancestor(c, t.level, level + 1));
    n = t.nodes[node];
    ++level;
  }
  *leaf_level = level;
  return node;
}

/// True when all three edge neighbours of cell c (level `level`) lie in c's ancestor at
/// `leaf_level`, so that a uniform leaf settles c's boundary flag without looking further.
/// In ancestor()'s terms (local row lr of 2^k, column offset in the block of 2^(k+1)), an up
/// ancestor holds offsets 0 .. 2 lr and a down one 2 lr + 1 .. 2^(k+1) - 1. The first and last cell
/// of such a run have a neighbour outside, and so do the up cells of an up ancestor's last row
/// (below) and the down cells of a down ancestor's first row (above).
QTMV_HD inline bool interior_of_ancestor(const grid::Cell& c, int level, int leaf_level) {
  const int k = level - leaf_level;
  const std::uint32_t lr = c.row & ((1u << k) - 1u);
  const std::uint32_t offset = c.col & ((2u << k) - 1u);
  if (offset <= 2 * lr) {  // up ancestor
    return offset > 0 && offset < 2 * lr && !(grid::is_up(c) && lr == (1u << k) - 1u);
  }
  return offset > 2 * lr + 1 && offset < (2u << k) - 1 && !(!grid::is_up(c) && lr == 0);
}

/// The m-th (0 <= m < 4^k) of the cells k levels below cell a, row by row from a's apex: local
/// row rr holds 2 rr + 1 cells (the jump cells' painting order on the GPU).
QTMV_HD inline grid::Cell descendant(const grid::Cell& a, int k, std::uint32_t m) {
  std::uint32_t rr = static_cast<std::uint32_t>(sqrtf(static_cast<float>(m)));
  while (rr * rr > m) --rr;
  while ((rr + 1) * (rr + 1) <= m) ++rr;
  const std::uint32_t cc = m - rr * rr;
  const std::uint32_t side = 1u << k, base = (a.col / 2) << (k + 1);
  const bool up = grid::is_up(a);
  const std::uint32_t r = up ? rr : side - 1 - rr;
  return {a.octant, (a.row << k) + r, up ? base + cc : base + 2 * r + 1 + cc};
}

/// The walk that builds the jump table: from the octant's root down to jump_level or a leaf.
QTMV_HD inline JumpEntry walk_to_jump_level(const TreeNode* nodes, const grid::Cell& c, int jump_level) {
  std::int32_t node = c.octant;
  int level = 0;
  for (; level < jump_level && nodes[node].count == kInternal; ++level) {
    node = nodes[node].value + child_digit(ancestor(c, jump_level, level + 1));
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
  if (!boundary_out) return;
  if (leaf.count == kUniform && interior_of_ancestor(c, t.level, leaf_level)) {
    *boundary_out = 0;
    return;
  }
  grid::Cell nb[3];
  grid::neighbours(c, t.level, nb);
  std::uint8_t boundary = 0;
  for (int k = 0; k < 3 && !boundary; ++k) {
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
    boundary = other_site != site;
  }
  *boundary_out = boundary;
}

}  // namespace qtmv::label
