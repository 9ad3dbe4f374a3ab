#include "label/cpu_painter.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "label/label_tree.hpp"
#include "label/outline_join.hpp"
#include "common/openmp_threads.hpp"
#include "label/piece_groups.hpp"

namespace qtmv::label {

namespace {

constexpr std::uint64_t kCpuBlock = 4096;  // cells per OpenMP work item

/// Boundary flags of [first, first + count) from its labels; neighbours outside the range are
/// labelled by `outside(code)`.
/// With `premarked`, cells whose flag is already 0 (inner cells of uniform leaves) are kept.
template <typename Outside>
void boundary_from_labels(int level, grid::Code first, std::uint64_t count, const std::int32_t* site,
                          std::uint8_t* boundary, int threads, const Outside& outside, bool premarked = false) {
  const std::int64_t blocks = static_cast<std::int64_t>((count + kCpuBlock - 1) / kCpuBlock);
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::uint64_t begin = static_cast<std::uint64_t>(b) * kCpuBlock;
    const std::uint64_t end = std::min(count, begin + kCpuBlock);
    grid::Cell c = grid::cell_of(first + begin, level);
    for (std::uint64_t k = begin; k < end; ++k) {
      if (!premarked || boundary[k] != 0) {
        grid::Code nb[3];
        grid::neighbours(c, first + k, level, nb);  // inside the octant, from the code alone
        std::uint8_t flag = 0;
        for (int s = 0; s < 3 && !flag; ++s) {
          const grid::Code code = nb[s];
          const std::int32_t other = code >= first && code - first < count ? site[code - first] : outside(code);
          flag = other != site[k];
        }
        boundary[k] = flag;
      }
      grid::next_in_code_order(c, level);
    }
  }
}


/// Whether the cell `code` of row `codes` of a node (row_codes_below) has all three neighbours in
/// the node: not a row's first or last cell, nor a cell on the node's base (the up cells of an
/// up node's last row, the down cells of a down node's first row). interior_of_ancestor's rule
/// along a row.
bool inner_in_row(grid::Code code, const grid::RowCodes& codes, bool base_row, bool up_node) {
  const bool down_cell = ((code - codes.row_start) & 1u) != 0;
  return code > codes.first && code < codes.last && !(base_row && (up_node ? !down_cell : down_cell));
}

/// The items of one list leaf in the order of a lower bound (chord) on their distance from any
/// point of the leaf, so that each cell's search (best) meets its nearest items first and stops
/// at the first item whose bound exceeds its best. Same best as best_of_list, tie included (the
/// winning piece among equals may differ, which the labels and distances do not show).
class LeafOrder {
 public:
  void make(const TreeView& tv, const TreeNode& leaf, const Vec3& centre, double radius) {
    leaf_ = leaf;
    order_.clear();
    any_group_ = false;
    for (std::int32_t k = 0; k < leaf.count && !any_group_; ++k) any_group_ = is_group_item(tv.lists[leaf.value + k]);
    if (!any_group_) return;  // pieces alone: best_of_list, in list order
    for (std::int32_t k = 0; k < leaf.count; ++k) {
      const std::int32_t item = tv.lists[leaf.value + k];
      double d, reach = 0.0;
      if (is_group_item(item)) {
        const PieceGroup& g = tv.groups[item_group(item)];
        d = std::sqrt(piece_chord2(centre, g.arc));
        reach = g.reach;
      } else {
        d = std::sqrt(piece_chord2(centre, tv.pieces[item]));
      }
      // Chords obey the triangle inequality, and a chord is shorter than its angle (radius).
      order_.push_back({d - reach - radius - kPruneMarginRadians, item});
    }
    std::sort(order_.begin(), order_.end(), [](const Entry& a, const Entry& b) {
      return a.lower != b.lower ? a.lower < b.lower : a.item < b.item;
    });
  }

  /// The best piece for x, a point of the leaf.
  Best best(const TreeView& tv, const Vec3& x) const {
    if (!any_group_) return best_of_list(tv, leaf_, x);
    Best best = no_best();
    std::int32_t won = -1;
    double bound = kChord2Infinity;  // squared chord that the best piece's distance cannot exceed
    // Pieces, and the groups' upper bounds; then the groups' subtrees, nearest first.
    for (const Entry& e : order_) {
      if (is_group_item(e.item)) {
        double lb2, ub2;
        std::int32_t site;
        item_bounds(x, e.item, tv.pieces, tv.groups, &lb2, &ub2, &site);
        bound = std::min(bound, ub2);
      } else {
        consider(best, piece_chord2(x, tv.pieces[e.item]), tv.pieces[e.item]);
      }
    }
    for (const Entry& e : order_) {
      const double limit = best.chord2 < bound ? best.chord2 : bound;
      if (e.lower > 0.0 && e.lower * e.lower > limit) break;  // so are all the items after it
      if (is_group_item(e.item)) search_group(x, item_group(e.item), tv.pieces, tv.groups, bound, best, won);
    }
    return best;
  }

 private:
  struct Entry {
    double lower;  ///< chord; may be negative
    std::int32_t item;
  };
  TreeNode leaf_{};
  bool any_group_ = false;
  std::vector<Entry> order_;
};

}  // namespace

LeafRows::LeafRows(const Tree& tree) : level_(tree.level) {
  for (std::size_t q = 0; q < tree.leaves.size(); ++q) {
    const TreeLeaf& leaf = tree.leaves[q];
    entries_[leaf.level][leaf.cell.octant].push_back({leaf.cell.row, static_cast<std::int64_t>(q)});
  }
  for (auto& level : entries_) {
    for (auto& octant : level) {
      std::sort(octant.begin(), octant.end(),
                [](const Entry& a, const Entry& b) { return a.row != b.row ? a.row < b.row : a.leaf < b.leaf; });
    }
  }
}

void LeafRows::meeting(grid::Code first, std::uint64_t count, std::vector<std::int64_t>& out) const {
  out.clear();
  if (count == 0) return;
  const grid::Cell a = grid::cell_of(first, level_), b = grid::cell_of(first + count - 1, level_);
  for (int o = a.octant; o <= b.octant; ++o) {
    const std::uint64_t r0 = o == a.octant ? a.row : 0;
    const std::uint64_t r1 = o == b.octant ? b.row : grid::rows_per_octant(level_) - 1;
    for (int l = 0; l <= level_; ++l) {
      const std::vector<Entry>& entries = entries_[l][o];
      const int k = level_ - l;  // the rows of level l hold 2^k rows of the level each
      const auto from = std::lower_bound(entries.begin(), entries.end(), r0 >> k,
                                         [](const Entry& e, std::uint64_t row) { return e.row < row; });
      for (auto e = from; e != entries.end() && e->row <= r1 >> k; ++e) out.push_back(e->leaf);
    }
  }
  std::sort(out.begin(), out.end());
}

std::uint64_t LeafRows::memory_bytes() const {
  std::uint64_t bytes = 0;
  for (const auto& level : entries_) {
    for (const auto& octant : level) bytes += octant.capacity() * sizeof(Entry);
  }
  return bytes;
}

/// The CPU's hier pass over [first, first + count): every leaf paints its cells, row run by row
/// run (a uniform leaf writes its site; a list leaf tests its candidates per cell), then the
/// boundary flags come from the labels.
void cpu_tree_range(const Tree& tree, const TreeView& tv, grid::Code first, std::uint64_t count,
                    std::int32_t* site, float* metres, std::uint8_t* boundary, int threads, const LeafRows* rows_of) {
  const int level = tree.level;
  const std::uint64_t end_code = first + count;
  std::vector<std::int64_t> meeting;  // the leaves to look at, when rows_of picks them
  if (rows_of) rows_of->meeting(first, count, meeting);
  const std::int64_t leaves = static_cast<std::int64_t>(rows_of ? meeting.size() : tree.leaves.size());
#pragma omp parallel num_threads(threads)
  {
  LeafOrder order;  // the list leaf's, per thread
  grid::CentreVectors centres;
#pragma omp for schedule(dynamic, 16)
  for (std::int64_t m = 0; m < leaves; ++m) {
    const TreeLeaf& leaf = tree.leaves[rows_of ? meeting[m] : m];
    const int k = level - leaf.level;
    const bool up = grid::is_up(leaf.cell);
    const std::uint64_t rows = std::uint64_t{1} << k;
    // Quick rejection by the leaf's code span.
    if (grid::row_codes_below(leaf.cell, k, rows - 1, level).last < first || grid::row_codes_below(leaf.cell, k, 0, level).first >= end_code) {
      continue;
    }
    const TreeNode node = tree.nodes[leaf.node];
    bool ordered = false;  // order made for this leaf
    for (std::uint64_t r = 0; r < rows; ++r) {
      const grid::RowCodes codes = grid::row_codes_below(leaf.cell, k, r, level);
      const std::uint64_t lo = std::max(codes.first, first), hi = std::min(codes.last + 1, end_code);
      if (lo >= hi) continue;
      if (node.count == kUniform) {
        std::fill(site + (lo - first), site + (hi - first), node.value);
        // With distances a uniform leaf is one site's fixed cells (build_tree): distance 0.
        if (metres) std::fill(metres + (lo - first), metres + (hi - first), 0.0f);
        if (boundary) {
          // Inner cells of the leaf (interior_of_ancestor) have all three neighbours in it: flag
          // 0 now; the others (1: to be decided) go through boundary_from_labels.
          const bool base_row = up ? r + 1 == rows : r == 0;
          for (std::uint64_t code = lo; code < hi; ++code) {
            boundary[code - first] = inner_in_row(code, codes, base_row, up) ? 0 : 1;
          }
        }
      } else {
        if (boundary) std::fill(boundary + (lo - first), boundary + (hi - first), std::uint8_t{1});
        if (!ordered) {
          order.make(tv, node, grid::cell_centre_vector(grid::code_of(leaf.cell, leaf.level), leaf.level),
                     node_radius(leaf.level, leaf.cell));
          ordered = true;
        }
        grid::Cell c = grid::cell_of(lo, level);
        for (std::uint64_t code = lo; code < hi; ++code, grid::next_in_code_order(c, level)) {
          const Best best = order.best(tv, centres(c, level));
          site[code - first] = best.site;
          if (metres) metres[code - first] = static_cast<float>(chord2_to_metres(best.chord2));
        }
      }
    }
  }
  }
  if (boundary) {
    boundary_from_labels(
        level, first, count, site, boundary, threads,
        [&](grid::Code code) { return tree_label(tv, grid::cell_of(code, level)); }, true);
  }
}

namespace {

bool same_cell(const grid::Cell& a, const grid::Cell& b) {
  return a.octant == b.octant && a.row == b.row && a.col == b.col;
}

/// A list leaf's cells of the labelling level with their sites, row by row from its apex (so in
/// code order), for its cells' neighbours inside it.
struct LeafLabels {
  grid::Cell leaf;
  int k = 0;                           ///< levels from the leaf down to the labelling level
  std::vector<grid::RowCodes> rows;    ///< the leaf's rows' codes
  std::vector<std::size_t> row_start;  ///< index of each row's first cell
  std::vector<std::int32_t> site;     ///< -1 until labelled
  std::vector<std::uint8_t> differs;  ///< a neighbour has another site (a boundary cell)

  /// Lists the cells of `leaf_cell` (of level `level - k`), unlabelled.
  void reset(const grid::Cell& leaf_cell, int leaf_k, int level) {
    leaf = leaf_cell;
    k = leaf_k;
    rows.clear();
    row_start.clear();
    std::size_t cells = 0;
    for (std::uint64_t r = 0; r < (std::uint64_t{1} << k); ++r) {
      rows.push_back(grid::row_codes_below(leaf, k, r, level));
      row_start.push_back(cells);
      cells += static_cast<std::size_t>(rows.back().last - rows.back().first + 1);
    }
    site.assign(cells, -1);
    differs.assign(cells, 0);
  }
  /// One past the index of row r's last cell.
  std::size_t row_end(std::size_t r) const { return row_start[r] + static_cast<std::size_t>(rows[r].last - rows[r].first + 1); }
};

/// Index of cell c (of the labelling level) among the cells of `leaf` (k levels up) in
/// LeafLabels' order: rows from the leaf's apex, an up leaf's row r holding 2r + 1 cells from its
/// base column, a down leaf's 2 (2^k - r) - 1 from two columns further per row.
std::size_t leaf_cell_index(const grid::Cell& leaf, int k, const grid::Cell& c) {
  const std::uint64_t r = c.row - (std::uint64_t{leaf.row} << k), base = std::uint64_t{leaf.col / 2} << (k + 1);
  if (grid::is_up(leaf)) return static_cast<std::size_t>(r * r + (c.col - base));
  const std::uint64_t side = std::uint64_t{1} << k;
  return static_cast<std::size_t>(2 * side * r - r * r + (c.col - (base + 2 * r + 1)));
}

/// A node below a list leaf whose cells all have one site.
struct SettledNode {
  grid::Cell cell;
  int level;
  std::int32_t site;
};

/// An item's lower bound (squared chord) and site, as one_site_below weighs them.
struct ItemBound {
  double lb2;
  std::int32_t site;
};

/// The centres and radii of the nodes that settle_below weighs, for one level: the children of a
/// node lie in two rows, so their latitudes' sines and their radii's stretch repeat.
struct NodeShapes {
  grid::CentreVectors centres;
  RadiusStretches stretches;
  double radius(int l, const grid::Cell& cell) { return node_radius(l, cell, stretches(l, cell.row)); }
};

/// The site of every cell of node `cell` (level l) when the list's items that can be nearest to
/// some point of it (those within prune_threshold of its centre, as build_tree keeps them) all
/// have one site; else -1. `shapes`: level l's; `bounds`: scratch.
std::int32_t one_site_below(const TreeView& tv, const TreeNode& list, const grid::Cell& cell, int l,
                            NodeShapes& shapes, std::vector<ItemBound>& bounds) {
  const Vec3 centre = shapes.centres(cell, l);
  const std::int32_t* items = tv.lists + list.value;
  bounds.resize(static_cast<std::size_t>(list.count));
  double min_ub2 = kChord2Infinity;
  for (std::int32_t k = 0; k < list.count; ++k) {
    double ub2;
    ItemBound& b = bounds[static_cast<std::size_t>(k)];
    item_bounds(centre, items[k], tv.pieces, tv.groups, &b.lb2, &ub2, &b.site);
    min_ub2 = std::min(min_ub2, ub2);
  }
  const double threshold = prune_threshold_above(min_ub2, shapes.radius(l, cell));
  std::int32_t one = -1;
  for (const ItemBound& b : bounds) {
    if (b.lb2 > threshold) continue;
    if (one >= 0 && b.site != one) return -1;
    one = b.site;
  }
  return one;
}

/// The settled nodes below node `cell` (level l) of a list leaf, down to a level above the
/// labelling level (single cells are searched anyway). `shapes`: one per level.
void settle_below(const TreeView& tv, const TreeNode& list, const grid::Cell& cell, int l, std::vector<SettledNode>& out,
                  NodeShapes* shapes, std::vector<ItemBound>& bounds) {
  if (l + 1 >= tv.level) return;
  grid::Cell kids[4];
  grid::children(cell, kids);
  for (const grid::Cell& kid : kids) {
    const std::int32_t site = one_site_below(tv, list, kid, l + 1, shapes[l + 1], bounds);
    if (site >= 0) {
      out.push_back({kid, l + 1, site});
    } else {
      settle_below(tv, list, kid, l + 1, out, shapes, bounds);
    }
  }
}

/// Whether the outline pass over `range` visits the leaf `cell` (of level leaf_level, in a tree of
/// `level`): whether its rows hold codes of the range.
bool leaf_visited(const grid::Cell& cell, int leaf_level, int level, grid::CodeRange range) {
  return grid::rows_meet(range, cell, leaf_level, level);
}

/// A thread's scratch for the outline pass: the visited leaf's order and labels; for the cells
/// across its edges, the leaf met last across each edge, the labels of the list leaves visited
/// last, and the orders of the list leaves last searched (a leaf's rows end on its left and right
/// neighbours in turn, so a few are kept, the oldest made again).
struct OutlineScratch {
  grid::CentreVectors centres;
  LeafOrder order;
  LeafLabels labels;
  static constexpr std::size_t kNeighbours = 4;
  LeafOrder neighbour[kNeighbours];
  std::int32_t neighbour_node[kNeighbours] = {-1, -1, -1, -1};
  std::size_t oldest = 0;
  std::vector<SettledNode> settled;
  NodeShapes shapes[grid::kMaxLevel + 1];  ///< settle_below's, per level
  std::vector<ItemBound> bounds;
  /// The leaf met last across each edge of the visited leaf (kNeighbourLeft, kNeighbourRight,
  /// kNeighbourVertical): consecutive cells along an edge mostly face one leaf.
  struct AcrossLeaf {
    grid::Cell cell{};
    int level = -1;  ///< -1: none yet
    std::int32_t node = -1;
  };
  AcrossLeaf across[3];
  grid::CodeRange range;  ///< of the pass
  /// The leaf that holds cell c, across `edge` of the visited leaf.
  const AcrossLeaf& across_leaf(const TreeView& tv, const grid::Cell& c, int edge) {
    AcrossLeaf& a = across[edge];
    if (a.level < 0 || !same_cell(grid::ancestor(c, tv.level, a.level), a.cell)) {
      a.node = find_leaf(tv, c, &a.level);
      a.cell = grid::ancestor(c, tv.level, a.level);
    }
    return a;
  }
  /// The labels of the list leaves this thread visited last: the leaves after them, often their
  /// siblings in the tree's order, border them.
  struct LabelledLeaf {
    std::int32_t node = -1;
    grid::Cell cell{};
    int k = 0;
    std::vector<std::int32_t> site;  ///< in LeafLabels' order
  };
  static constexpr std::size_t kLabelled = 8;
  LabelledLeaf labelled[kLabelled];
  std::size_t next_labelled = 0;
  /// Keeps `labels` (of leaf `node`) among the labelled leaves, in place of the oldest.
  void keep_labels(std::int32_t node) {
    LabelledLeaf& kept = labelled[next_labelled];
    next_labelled = (next_labelled + 1) % kLabelled;
    kept.node = node;
    kept.cell = labels.leaf;
    kept.k = labels.k;
    kept.site.assign(labels.site.begin(), labels.site.end());
  }
  /// The site of cell c in leaf `node` (of level leaf_level).
  std::int32_t site_in_leaf(const TreeView& tv, const grid::Cell& c, std::int32_t node, int leaf_level) {
    const TreeNode leaf = tv.nodes[node];
    if (leaf.count == kUniform) return leaf.value;
    for (const LabelledLeaf& l : labelled) {
      if (l.node == node) return l.site[leaf_cell_index(l.cell, l.k, c)];
    }
    std::size_t slot = 0;
    while (slot < kNeighbours && neighbour_node[slot] != node) ++slot;
    if (slot == kNeighbours) {
      slot = oldest;
      oldest = (oldest + 1) % kNeighbours;
      const grid::Cell at = grid::ancestor(c, tv.level, leaf_level);
      neighbour[slot].make(tv, leaf, grid::cell_centre_vector(grid::code_of(at, leaf_level), leaf_level),
                           node_radius(leaf_level, at));
      neighbour_node[slot] = node;
    }
    return neighbour[slot].best(tv, centres(c, tv.level)).site;
  }
};

/// True when the cell `c` of level `l` lies in a uniform leaf of `site` (at level l or above).
bool in_uniform_leaf_of(const TreeView& tv, const grid::Cell& c, int l, std::int32_t site) {
  // The walk down to level l, from the jump table's entry where l is below its level.
  JumpEntry at{c.octant, 0};
  if (l >= tv.jump_level) at = tv.jump[grid::code_of(grid::ancestor(c, l, tv.jump_level), tv.jump_level)];
  std::int32_t node = at.node;
  for (int level = at.level; level < l && tv.nodes[node].count == kInternal; ++level) {
    node = tv.nodes[node].value + grid::child_digit(grid::ancestor(c, l, level + 1));
  }
  return tv.nodes[node].count == kUniform && tv.nodes[node].value == site;
}

/// One leaf's visit by the outline pass: which visit settles a pair of cells across the leaf's
/// edges, and the cells it lists then.
///
/// A pair of a list leaf's cell and a uniform leaf's is settled by the list leaf's visit, which
/// then lists the uniform leaf's cell too (a uniform leaf's rim beside a list leaf would
/// otherwise search the list leaf's cells again); the uniform leaf's visit leaves the pair to a
/// list leaf that the pass visits. A pair of two list leaves' cells is settled by the later leaf
/// in the tree's order (the higher node) where the pass visits it, likewise listing both: the
/// earlier leaf's labels are then often still at hand (OutlineScratch::labelled), whereas the
/// earlier leaf would have to search the later one's cells. join_outline_parts lists a cell
/// listed twice once.
struct LeafVisit {
  const TreeView& tv;
  const TreeLeaf& leaf;
  bool list_leaf;
  OutlineScratch& scratch;
  OutlineCells& out;

  /// Whether no cell of `site` beside leaf `a` has to ask: `a` is uniform with that site, or a
  /// visited list leaf that settles the pairs.
  bool nothing_to_ask(const OutlineScratch::AcrossLeaf& a, std::int32_t site) const {
    const TreeNode other = tv.nodes[a.node];
    if (other.count == kUniform) return other.value == site;
    return (!list_leaf || a.node > leaf.node) && leaf_visited(a.cell, a.level, tv.level, scratch.range);
  }
  /// Whether the neighbour nb of a cell of `site`, in leaf `a` across an edge of this leaf, has
  /// another site, where nothing_to_ask(a, site) does not settle it.
  bool differs_in(const grid::Cell& nb, const OutlineScratch::AcrossLeaf& a, std::int32_t site) const {
    const TreeNode other = tv.nodes[a.node];
    if (other.count == kUniform) {  // of another site
      if (list_leaf) out.push_back({grid::code_of(nb, tv.level), other.value, 1u});
      return true;
    }
    const std::int32_t other_site = scratch.site_in_leaf(tv, nb, a.node, a.level);
    if (other_site == site) return false;
    if (list_leaf && a.node < leaf.node) out.push_back({grid::code_of(nb, tv.level), other_site, 1u});
    return true;
  }
};

/// Labels every cell of the list leaf `leaf` (node `node`) into scratch.labels, and keeps them
/// among the thread's labelled leaves.
void label_list_leaf(const TreeView& tv, const TreeLeaf& leaf, const TreeNode& node, OutlineScratch& scratch) {
  LeafOrder& order = scratch.order;
  LeafLabels& labels = scratch.labels;
  const int level = tv.level;
  const int k = level - leaf.level;
  const std::uint64_t rows = std::uint64_t{1} << k;
  labels.reset(leaf.cell, k, level);
  order.make(tv, node, grid::cell_centre_vector(grid::code_of(leaf.cell, leaf.level), leaf.level),
             node_radius(leaf.level, leaf.cell));
  // Nodes below the leaf whose kept items all have one site (the build's own rule, carried on
  // below the list level): their cells need no search.
  scratch.settled.clear();
  settle_below(tv, node, leaf.cell, leaf.level, scratch.settled, scratch.shapes, scratch.bounds);
  // The settled nodes' cells take their sites, row by row; the others are searched.
  for (const SettledNode& n : scratch.settled) {
    const int nk = level - n.level;
    const std::uint64_t node_rows = std::uint64_t{1} << nk;
    for (std::uint64_t r = 0; r < node_rows; ++r) {
      const grid::RowCodes codes = grid::row_codes_below(n.cell, nk, r, level);
      const std::size_t leaf_row = static_cast<std::size_t>((std::uint64_t{n.cell.row} << nk) + r - (std::uint64_t{leaf.cell.row} << k));
      const std::size_t at = labels.row_start[leaf_row] + static_cast<std::size_t>(codes.first - labels.rows[leaf_row].first);
      std::fill_n(labels.site.begin() + static_cast<std::ptrdiff_t>(at), codes.last - codes.first + 1, n.site);
    }
  }
  for (std::uint64_t r = 0; r < rows; ++r) {
    grid::Cell c = grid::cell_of(labels.rows[r].first, level);
    for (std::size_t m = labels.row_start[r]; m < labels.row_end(r); ++m, grid::next_in_code_order(c, level)) {
      if (labels.site[m] < 0) labels.site[m] = order.best(tv, scratch.centres(c, level)).site;
    }
  }
  scratch.keep_labels(leaf.node);
}

/// The outline cells of a leaf all of whose cells have `site` (a uniform leaf, or a list leaf
/// whose cells all got one site).
void one_site_leaf_outline(const LeafVisit& visit, std::int32_t site) {
  const TreeView& tv = visit.tv;
  const TreeLeaf& leaf = visit.leaf;
  OutlineScratch& scratch = visit.scratch;
  const int level = tv.level;
  const int k = level - leaf.level;
  const std::uint64_t rows = std::uint64_t{1} << k;
  // A leaf of one site lists cells along its edges only, edge by edge: the left edge holds each
  // row's first cell, the right edge each row's last, the base edge the up cells of an up leaf's
  // last row (the down cells of a down leaf's first row). Along an edge whose neighbour (of the
  // leaf's level) lies in a uniform leaf of the same site no cell is a boundary cell, since the
  // cells across it lie in that neighbour: such an edge lists only the row ends on it (on the
  // octant's left edge, column 0, or its right edge, column 2 row). A corner cell, on two edges,
  // is listed by each (join_outline_parts keeps it once).
  grid::Cell around[3];
  grid::neighbours(leaf.cell, leaf.level, around);
  bool settled[3];
  for (int s = 0; s < 3; ++s) settled[s] = in_uniform_leaf_of(tv, around[s], leaf.level, site);
  const bool up_leaf = grid::is_up(leaf.cell);
  const grid::Code octant_first = static_cast<grid::Code>(leaf.cell.octant) * grid::cells_per_octant(level);
  const std::uint32_t first_row = leaf.cell.row << k;
  const std::uint32_t base = (leaf.cell.col / 2) << (k + 1);  // the leaf's first column in its rows' blocks
  // The cells of edge s, n of them, the m-th in (row_of(m), col_of(m)). Where the leaf across
  // a cell asks nothing of it, the cells after it that face the same leaf ask nothing either:
  // `beyond(a)` is the index past them (the leaf across a side edge is a triangle whose
  // matching edge runs along it, holding the across cells of all its rows; across the base it
  // holds a run of the next row's columns).
  const auto walk_edge = [&](int s, std::uint32_t n, auto row_of, auto col_of, auto beyond) {
    for (std::uint32_t m = 0; m < n;) {
      const grid::Cell c{leaf.cell.octant, row_of(m), col_of(m)};
      std::uint32_t next = m + 1;
      bool boundary = false;
      if (!settled[s]) {
        grid::Cell nb[3];
        grid::neighbours(c, level, nb);
        const OutlineScratch::AcrossLeaf& a = scratch.across_leaf(tv, nb[s], s);
        if (visit.nothing_to_ask(a, site)) {
          next = std::max(next, std::min(n, beyond(a)));
        } else {
          boundary = visit.differs_in(nb[s], a, site);
        }
      }
      for (; m < next; ++m) {
        const grid::Cell e{leaf.cell.octant, row_of(m), col_of(m)};
        if (boundary || is_row_end(e)) {
          visit.out.push_back({octant_first + std::uint64_t{e.row} * e.row + e.col, site, boundary ? 1u : 0u});
        }
      }
    }
  };
  // Past the rows of leaf a (in its octant; the side edges keep the row across octants).
  const auto past_rows = [&](const OutlineScratch::AcrossLeaf& a) {
    const std::uint32_t end = (a.cell.row + 1) << (level - a.level);
    return end > first_row ? end - first_row : 0u;
  };
  const std::uint32_t n = static_cast<std::uint32_t>(rows);
  const std::uint32_t last_col = base + 2 * n - 1;  // of a down leaf's rows
  const auto row_at = [&](std::uint32_t m) { return first_row + m; };
  if (!settled[grid::kNeighbourLeft] || leaf.cell.col == 0) {
    walk_edge(grid::kNeighbourLeft, n, row_at, [&](std::uint32_t m) { return up_leaf ? base : base + 2 * m + 1; },
              past_rows);
  }
  if (!settled[grid::kNeighbourRight] || leaf.cell.col == 2 * leaf.cell.row) {
    walk_edge(grid::kNeighbourRight, n, row_at, [&](std::uint32_t m) { return up_leaf ? base + 2 * m : last_col; },
              past_rows);
  }
  if (!settled[grid::kNeighbourVertical]) {
    const std::uint32_t row = up_leaf ? first_row + n - 1 : first_row;
    // The leaf across holds the columns up to its own base's last in the next row (an up
    // leaf's base) or the row before (a down leaf's); past the octant's last row the
    // columns run the other way, so each cell asks.
    const bool mirrored = up_leaf && std::uint64_t{row} + 1 == grid::rows_per_octant(level);
    walk_edge(grid::kNeighbourVertical, n, [&](std::uint32_t) { return row; },
              [&](std::uint32_t m) { return (up_leaf ? base : base + 1) + 2 * m; },
              [&](const OutlineScratch::AcrossLeaf& a) -> std::uint32_t {
                if (mirrored) return 0;
                const int ka = level - a.level;
                const std::uint32_t a_end = ((a.cell.col / 2) << (ka + 1)) + (2u << ka);  // its columns' block end
                return a_end > base ? (a_end - base) / 2 : 0u;
              });
  }
}

/// The outline cells of a list leaf of several sites, from its labels (label_list_leaf).
void list_leaf_outline(const LeafVisit& visit) {
  const TreeView& tv = visit.tv;
  const TreeLeaf& leaf = visit.leaf;
  OutlineScratch& scratch = visit.scratch;
  LeafLabels& labels = scratch.labels;
  const int level = tv.level;
  const int k = level - leaf.level;
  const std::uint64_t rows = std::uint64_t{1} << k;
  // Pairs of cells inside the leaf, each compared once, row by row from the apex: the neighbours
  // along each row, then each row's down cells with their neighbours in the row before (one place
  // before in an up leaf, whose rows grow by two cells from one first column; one place after in a
  // down leaf, whose rows shrink by two and whose first cells are down cells).
  std::vector<std::uint8_t>& differs = labels.differs;
  const bool up_leaf = grid::is_up(leaf.cell);
  for (std::uint64_t r = 0; r < rows; ++r) {
    const std::size_t first = labels.row_start[r], end = labels.row_end(r);
    for (std::size_t m = first; m + 1 < end; ++m) {
      if (labels.site[m] != labels.site[m + 1]) differs[m] = differs[m + 1] = 1;
    }
    if (r == 0) continue;
    const std::size_t above = labels.row_start[r - 1];
    for (std::size_t p = up_leaf ? 1 : 0; first + p < end; p += 2) {
      const std::size_t q = up_leaf ? above + p - 1 : above + p + 1;
      if (labels.site[first + p] != labels.site[q]) differs[first + p] = differs[q] = 1;
    }
  }
  // The cells on the leaf's edges ask across them: each row's first cell its left neighbour, its
  // last cell its right one, and the base row's cells on the base (an up leaf's last row's up
  // cells, a down leaf's first row's down cells: even places) their vertical one. Then the
  // boundary cells and the octant's row ends are listed.
  const std::uint32_t first_row = leaf.cell.row << k;
  const std::uint32_t base = (leaf.cell.col / 2) << (k + 1);  // the leaf's first column in its rows' blocks
  const std::uint64_t base_row = up_leaf ? rows - 1 : 0;
  for (std::uint64_t r = 0; r < rows; ++r) {
    const std::size_t first = labels.row_start[r], end = labels.row_end(r);
    const std::uint32_t row = first_row + static_cast<std::uint32_t>(r);
    const std::uint32_t first_col = up_leaf ? base : base + 2 * static_cast<std::uint32_t>(r) + 1;
    const grid::Code first_code = labels.rows[r].first;
    const bool on_base = r == base_row;
    for (std::size_t m = first; m < end;) {
      const std::size_t p = m - first;
      const grid::Cell c{leaf.cell.octant, row, first_col + static_cast<std::uint32_t>(p)};
      const bool ask[3] = {m == first, m + 1 == end, on_base && p % 2 == 0};
      if (ask[0] || ask[1] || ask[2]) {
        const std::int32_t site = labels.site[m];
        grid::Cell nb[3];
        grid::neighbours(c, level, nb);
        bool boundary = differs[m] != 0;
        for (int s = 0; s < 3; ++s) {
          if (!ask[s]) continue;
          const OutlineScratch::AcrossLeaf& a = scratch.across_leaf(tv, nb[s], s);
          boundary = (!visit.nothing_to_ask(a, site) && visit.differs_in(nb[s], a, site)) || boundary;
        }
        if (boundary || is_row_end(c)) visit.out.push_back({first_code + p, site, boundary ? 1u : 0u});
      } else if (differs[m]) {
        visit.out.push_back({first_code + p, labels.site[m], 1u});
      }
      // Off the base row only a row's first and last cells ask across: skip the cells between
      // them that differ from no neighbour inside.
      ++m;
      if (!on_base) {
        while (m + 1 < end && !differs[m]) ++m;
      }
    }
  }
}

/// Visits one leaf: every cell of a list leaf, the rim of a uniform leaf (or of a list leaf
/// whose cells all got one site); appends the outline cells among them. A leaf of one site whose
/// three neighbours (of its level) lie in uniform leaves of that site has no boundary cell: only
/// its row ends are listed.
void leaf_outline_cells(const TreeView& tv, const TreeLeaf& leaf, const TreeNode& node, OutlineScratch& scratch,
                        OutlineCells& out) {
  const LeafVisit visit{tv, leaf, node.count != kUniform, scratch, out};
  if (!visit.list_leaf) {
    one_site_leaf_outline(visit, node.value);
    return;
  }
  label_list_leaf(tv, leaf, node, scratch);
  const LeafLabels& labels = scratch.labels;
  if (std::all_of(labels.site.begin(), labels.site.end(), [&](std::int32_t s) { return s == labels.site[0]; })) {
    one_site_leaf_outline(visit, labels.site[0]);
  } else {
    list_leaf_outline(visit);
  }
}

}  // namespace

std::vector<OutlineCells> cpu_tree_outline_parts(const Tree& tree, const TreeView& tv, int threads, grid::CodeRange range,
                                                 const std::function<void(double)>& done) {
  const std::size_t leaves = tree.leaves.size();
  std::vector<OutlineCells> parts(static_cast<std::size_t>(threads));
  std::vector<OutlineScratch> scratch(static_cast<std::size_t>(threads));
  for (OutlineScratch& s : scratch) s.range = range;
  // Leaves in batches, so that `done` (which may throw to stop the run) is called every so often.
  const std::size_t batch = std::max<std::size_t>(4096, leaves / 256);
  for (std::size_t first = 0; first < leaves; first += batch) {
    const std::size_t last = std::min(leaves, first + batch);
#pragma omp parallel num_threads(threads)
    {
      const auto t = static_cast<std::size_t>(thread_index());
#pragma omp for schedule(dynamic, 16)
      for (std::int64_t q = static_cast<std::int64_t>(first); q < static_cast<std::int64_t>(last); ++q) {
        const TreeLeaf& leaf = tree.leaves[static_cast<std::size_t>(q)];
        if (!leaf_visited(leaf.cell, leaf.level, tree.level, range)) continue;
        leaf_outline_cells(tv, leaf, tree.nodes[static_cast<std::size_t>(leaf.node)], scratch[t], parts[t]);
      }
    }
    if (done) done(static_cast<double>(last) / static_cast<double>(leaves));
  }
  return parts;
}

OutlineCells cpu_tree_outlines(const Tree& tree, const TreeView& tv, int threads, grid::CodeRange range,
                               const std::function<void(double)>& done) {
  std::vector<OutlineCells> parts = cpu_tree_outline_parts(tree, tv, threads, range, done);
  return join_outline_parts(parts, tree.level, range, threads);
}

void append_outline_cells(int level, grid::Code first, std::uint64_t count, const std::int32_t* site,
                          const std::uint8_t* boundary, int threads, OutlineCells* out) {
  // Each block's outline cells are counted first (its boundary flags, and its row ends that are
  // not boundary cells), so that all are written once, in place, on all threads.
  const std::int64_t blocks = static_cast<std::int64_t>((count + kCpuBlock - 1) / kCpuBlock);
  std::vector<std::uint64_t> at(static_cast<std::size_t>(blocks) + 1, 0);
  const std::uint64_t rows = grid::rows_per_octant(level);
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::uint64_t begin = static_cast<std::uint64_t>(b) * kCpuBlock;
    const std::uint64_t end = std::min(count, begin + kCpuBlock);
    std::uint64_t n = 0;
    for (std::uint64_t k = begin; k < end; ++k) n += boundary[k] != 0 ? 1 : 0;
    // The row ends in the block: row i of an octant starts at its code i^2 and ends 2i later.
    const grid::Cell c = grid::cell_of(first + begin, level);
    grid::Code octant_first = static_cast<grid::Code>(c.octant) * grid::cells_per_octant(level);
    for (std::uint64_t i = c.row;; ++i) {
      if (i == rows) {
        octant_first += grid::cells_per_octant(level);
        i = 0;
      }
      const grid::Code row_first = octant_first + i * i;
      if (row_first >= first + end) break;
      const auto row_end_only = [&](grid::Code e) {
        return e >= first + begin && e < first + end && boundary[e - first] == 0 ? 1u : 0u;
      };
      n += row_end_only(row_first) + (i > 0 ? row_end_only(row_first + 2 * i) : 0u);
    }
    at[static_cast<std::size_t>(b) + 1] = n;
  }
  for (std::size_t b = 0; b < static_cast<std::size_t>(blocks); ++b) at[b + 1] += at[b];
  const std::size_t base = out->size();
  out->resize(base + at[static_cast<std::size_t>(blocks)]);  // not zeroed
  OutlineCell* const cells = out->data() + base;
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::uint64_t begin = static_cast<std::uint64_t>(b) * kCpuBlock;
    const std::uint64_t end = std::min(count, begin + kCpuBlock);
    OutlineCell* next = cells + at[static_cast<std::size_t>(b)];
    grid::Cell c = grid::cell_of(first + begin, level);
    for (std::uint64_t k = begin; k < end; ++k, grid::next_in_code_order(c, level)) {
      if (boundary[k] != 0 || is_row_end(c)) *next++ = {first + k, site[k], boundary[k] != 0 ? 1u : 0u};
    }
  }
}

void cpu_brute_range(const std::vector<Piece>& candidates, int level, grid::Code first, std::uint64_t count,
                     std::int32_t* site, float* metres, std::uint8_t* boundary, int threads) {
  const std::int64_t n = static_cast<std::int64_t>(count);
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) {
    const Best best = reference_best(candidates, first + static_cast<std::uint64_t>(k), level);
    site[k] = best.site;
    if (metres) metres[k] = static_cast<float>(chord2_to_metres(best.chord2));
  }
  if (!boundary) return;
  boundary_from_labels(level, first, count, site, boundary, threads,
                       [&](grid::Code code) { return reference_best(candidates, code, level).site; });
}

}  // namespace qtmv::label
