#include "label/cpu_painter.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "label/label_tree.hpp"
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
        grid::Cell nb[3];
        grid::neighbours(c, level, nb);
        std::uint8_t flag = 0;
        for (int s = 0; s < 3 && !flag; ++s) {
          const grid::Code code = grid::code_of(nb[s], level);
          const std::int32_t other = code >= first && code - first < count ? site[code - first] : outside(code);
          flag = other != site[k];
        }
        boundary[k] = flag;
      }
      grid::next_in_code_order(c, level);
    }
  }
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
    double bound = 1e300;  // squared chord that the best piece's distance cannot exceed
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

/// The CPU's hier pass over [first, first + count): every leaf paints its cells, row run by row
/// run (a uniform leaf writes its site; a list leaf tests its candidates per cell), then the
/// boundary flags come from the labels.
void cpu_tree_range(const Tree& tree, const TreeView& tv, grid::Code first, std::uint64_t count,
                    std::int32_t* site, float* metres, std::uint8_t* boundary, int threads) {
  const int level = tree.level;
  const std::uint64_t end_code = first + count;
  const std::int64_t leaves = static_cast<std::int64_t>(tree.leaves.size());
#pragma omp parallel num_threads(threads)
  {
  LeafOrder order;  // the list leaf's, per thread
#pragma omp for schedule(dynamic, 16)
  for (std::int64_t q = 0; q < leaves; ++q) {
    const TreeLeaf& leaf = tree.leaves[q];
    const TreeNode node = tree.nodes[leaf.node];
    const int k = level - leaf.level;
    const bool up = grid::is_up(leaf.cell);
    const std::uint64_t rows = std::uint64_t{1} << k;
    // Quick rejection by the leaf's code span.
    if (grid::row_codes_below(leaf.cell, k, rows - 1, level).last < first || grid::row_codes_below(leaf.cell, k, 0, level).first >= end_code) {
      continue;
    }
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
          const bool edge_row = up ? r + 1 == rows : r == 0;
          for (std::uint64_t code = lo; code < hi; ++code) {
            const bool odd = ((code - codes.row_start) & 1u) != 0;  // a down cell
            const bool inner = code > codes.first && code < codes.last && !(edge_row && (up ? !odd : odd));
            boundary[code - first] = inner ? 0 : 1;
          }
        }
      } else {
        if (boundary) std::fill(boundary + (lo - first), boundary + (hi - first), std::uint8_t{1});
        if (!ordered) {
          order.make(tv, node, grid::cell_centre_vector(grid::code_of(leaf.cell, leaf.level), leaf.level),
                     node_radius(leaf.level, leaf.cell));
          ordered = true;
        }
        for (std::uint64_t code = lo; code < hi; ++code) {
          const Best best = order.best(tv, grid::cell_centre_vector(code, level));
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
