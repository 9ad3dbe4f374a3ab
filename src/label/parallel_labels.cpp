// Labels of points along parallels from the host's tree (parallel_labels.hpp).
#include "label/parallel_labels.hpp"

#include <algorithm>
#include <vector>

#include "grid/qtm.hpp"

namespace qtmv::label {

namespace {

/// The site of every cell of a leaf, or -1 when its candidates have several sites (a list
/// leaf's cells take the site of one of its items; a group's pieces are its site's).
std::int32_t leaf_site(const TreeView& tv, const TreeNode& leaf) {
  if (leaf.count == kUniform) return leaf.value;
  std::int32_t site = -1;
  for (std::int32_t k = 0; k < leaf.count; ++k) {
    const std::int32_t item = tv.lists[leaf.value + k];
    const std::int32_t s = is_group_item(item) ? tv.groups[item_group(item)].arc.site : tv.pieces[item].site;
    if (site >= 0 && s != site) return -1;
    site = s;
  }
  return site;
}

/// True when every cell across the three edges of cell `a` (of `leaf_level`, a leaf of one site)
/// lies in a leaf of `site` at level leaf_level or above: then no cell of `a` is a boundary cell,
/// since a cell's edge neighbours lie in its own ancestor or in the ancestor's neighbour across
/// that edge (jump_cell_clean's argument).
bool edges_hold_site(const TreeView& tv, const grid::Cell& a, int leaf_level, std::int32_t site) {
  grid::Cell across[3];
  grid::neighbours(a, leaf_level, across);
  const int k = tv.level - leaf_level;
  for (const grid::Cell& n : across) {
    int level;
    const std::int32_t other = find_leaf(tv, grid::descendant(n, k, 0), &level);
    if (level > leaf_level || leaf_site(tv, tv.nodes[other]) != site) return false;
  }
  return true;
}

/// The columns [first, last] of row `row` (of the labelling level, k levels below cell `a`) that
/// lie in `a`: ancestor()'s blocks read backwards.
struct ColumnSpan {
  std::uint64_t first, last;
  bool holds(std::uint64_t j) const { return j >= first && j <= last; }
};
ColumnSpan columns_below(const grid::Cell& a, std::uint64_t row, int k) {
  const std::uint64_t local_row = row & ((std::uint64_t{1} << k) - 1);
  const std::uint64_t base = std::uint64_t{a.col / 2} << (k + 1);
  if (grid::is_up(a)) return {base, base + 2 * local_row};
  return {base + 2 * local_row + 1, base + (std::uint64_t{2} << k) - 1};
}

/// The labels of one thread's rows.
class ParallelLabeller {
 public:
  ParallelLabeller(const TreeView& tv, bool with_boundary)
      : tv_(tv), with_boundary_(with_boundary), facts_(with_boundary ? kFacts : 0) {}

  /// Point k of the row at entry k of site, metres and boundary (each may be null but site).
  void row(double lat, const double* lon, std::size_t count, std::int32_t* site, float* metres,
           std::uint8_t* boundary) {
    const grid::ParallelCells parallel(lat, tv_.level);
    out_ = {site, metres, boundary};
    for (std::size_t begin = 0; begin < count;) {
      // A run of ascending longitudes of one quadrant: its columns ascend (north) or descend.
      const int q = grid::ParallelCells::quadrant_of(lon[begin]);
      std::size_t end = begin + 1;
      while (end < count && lon[end] >= lon[end - 1] && grid::ParallelCells::quadrant_of(lon[end]) == q) ++end;
      run(parallel, q, lon, begin, end);
      begin = end;
    }
  }

 private:
  struct Out {
    std::int32_t* site;
    float* metres;
    std::uint8_t* boundary;
  };
  /// A leaf's facts, kept per thread (direct-mapped by node): the one site of its cells (-1:
  /// several) and whether no cell of it is a boundary cell.
  struct LeafFacts {
    std::int32_t node = -1;
    std::int32_t site = -1;
    bool clean = false;
  };
  static constexpr std::size_t kFacts = std::size_t{1} << 12;

  const LeafFacts& facts(std::int32_t node, const grid::Cell& a, int leaf_level) {
    LeafFacts& f = facts_[static_cast<std::uint32_t>(node) & (kFacts - 1)];
    if (f.node != node) {
      f.node = node;
      f.site = leaf_site(tv_, tv_.nodes[node]);
      f.clean = f.site >= 0 && edges_hold_site(tv_, a, leaf_level, f.site);
    }
    return f;
  }

  void run(const grid::ParallelCells& parallel, int q, const double* lon, std::size_t begin, std::size_t end) {
    const int octant = parallel.octant(q);
    const std::uint64_t row = parallel.row();
    const auto column = [&](std::size_t x) { return parallel.column(parallel.local_lon(q, lon[x])); };
    std::size_t x = begin;
    std::uint64_t j = column(x);
    while (x < end) {
      const grid::Cell c{octant, static_cast<std::uint32_t>(row), static_cast<std::uint32_t>(j)};
      int leaf_level;
      const std::int32_t leaf_index = find_leaf(tv_, c, &leaf_level);
      const TreeNode leaf = tv_.nodes[leaf_index];
      const grid::Cell a = grid::ancestor(c, tv_.level, leaf_level);
      const ColumnSpan span = columns_below(a, row, tv_.level - leaf_level);
      const LeafFacts* f = with_boundary_ ? &facts(leaf_index, a, leaf_level) : nullptr;
      if (leaf.count == kUniform) {
        const std::size_t stop = end_of_span(column, span, x, end);
        std::fill(out_.site + x, out_.site + stop, leaf.value);
        // With distances a uniform leaf is one site's fixed cells (build_tree): distance 0.
        if (out_.metres) std::fill(out_.metres + x, out_.metres + stop, 0.0f);
        if (f && f->clean) std::fill(out_.boundary + x, out_.boundary + stop, std::uint8_t{0});
        if (f && !f->clean) {
          for (std::size_t y = x; y < stop; ++y) {
            const grid::Cell cy{octant, static_cast<std::uint32_t>(row), static_cast<std::uint32_t>(y == x ? j : column(y))};
            out_.boundary[y] = tree_boundary_flag(tv_, cy, leaf_index, leaf_level, leaf.value);
          }
        }
        x = stop;
        if (x < end) j = column(x);
        continue;
      }
      // A list leaf: its candidates for each cell, once per cell (neighbouring points may share one).
      std::uint64_t last = ~std::uint64_t{0};
      while (x < end && span.holds(j)) {
        if (j == last) {
          copy_entry(x - 1, x);
        } else {
          const grid::Cell cx{octant, static_cast<std::uint32_t>(row), static_cast<std::uint32_t>(j)};
          const Best best = best_of_list(tv_, leaf, centres_(cx, tv_.level));
          out_.site[x] = best.site;
          if (out_.metres) out_.metres[x] = static_cast<float>(chord2_to_metres(best.chord2));
          if (f) {
            // A leaf of one site: its inner cells' neighbours are its own cells.
            const bool settled = f->clean || (f->site >= 0 && grid::interior_of_ancestor(cx, tv_.level, leaf_level));
            out_.boundary[x] = settled ? 0 : tree_boundary_flag(tv_, cx, leaf_index, leaf_level, best.site);
          }
          last = j;
        }
        ++x;
        if (x < end) j = column(x);
      }
    }
  }

  /// The first point after x (or `end`) whose column lies outside `span`: the columns along a run
  /// are monotone (every step of ParallelCells::column is), so the span's points are consecutive;
  /// a galloping search, then bisection.
  template <typename Column>
  static std::size_t end_of_span(const Column& column, const ColumnSpan& span, std::size_t x, std::size_t end) {
    std::size_t inside = x, outside = end;
    for (std::size_t step = 1;; step *= 2) {
      const std::size_t probe = inside + step;
      if (probe >= end) break;
      if (!span.holds(column(probe))) {
        outside = probe;
        break;
      }
      inside = probe;
    }
    while (outside - inside > 1) {
      const std::size_t mid = inside + (outside - inside) / 2;
      if (span.holds(column(mid))) {
        inside = mid;
      } else {
        outside = mid;
      }
    }
    return outside;
  }

  void copy_entry(std::size_t from, std::size_t to) {
    out_.site[to] = out_.site[from];
    if (out_.metres) out_.metres[to] = out_.metres[from];
    if (out_.boundary) out_.boundary[to] = out_.boundary[from];
  }

  const TreeView& tv_;
  bool with_boundary_;
  std::vector<LeafFacts> facts_;
  grid::CentreVectors centres_;
  Out out_{};
};

}  // namespace

void tree_label_parallels(const TreeView& tv, const double* lat, int rows, const double* lon, std::size_t count,
                          std::int32_t* site, float* metres, std::uint8_t* boundary, int threads) {
#pragma omp parallel num_threads(threads)
  {
    ParallelLabeller labeller(tv, boundary != nullptr);
#pragma omp for schedule(dynamic, 1)
    for (int r = 0; r < rows; ++r) {
      const std::size_t at = static_cast<std::size_t>(r) * count;
      labeller.row(lat[r], lon, count, site + at, metres ? metres + at : nullptr, boundary ? boundary + at : nullptr);
    }
  }
}

}  // namespace qtmv::label
