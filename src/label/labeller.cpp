// The labeller's host side: input checks, candidates, the pruned tree, the CPU paths (OpenMP),
// device choice, tiling, and the hand-over to the CUDA back end.
#include "label/labeller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>

#include "common/device_spec.hpp"
#include "common/host_info.hpp"
#include "grid/qtm_checks.hpp"
#include "label/label_cuda.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_node_rule.hpp"

#ifdef _OPENMP
#include <omp.h>
#include <parallel/algorithm>
#endif

namespace qtmv::label {

namespace {

int thread_count(int requested) {
#ifdef _OPENMP
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

bool is_unit(const Vec3& v) {
  const double n = grid::dot(v, v);
  return std::isfinite(n) && std::fabs(n - 1.0) < 1e-9;
}

void validate(const LabelInput& in, Rule rule) {
  grid::require_level(in.level);
  if (in.site_count <= 0) throw std::invalid_argument("there are no sites to label with");
  auto check_site = [&](std::int32_t site, const char* what) {
    if (site < 0 || site >= in.site_count) {
      throw std::invalid_argument(std::string(what) + " has site id " + std::to_string(site) +
                                  ", outside 0.." + std::to_string(in.site_count - 1));
    }
  };
  for (std::size_t k = 0; k < in.piece_count; ++k) {
    const SitePiece& p = in.pieces[k];
    check_site(p.site, "a site piece");
    if (!is_unit(p.a) || !is_unit(p.b)) {
      throw std::invalid_argument("site piece " + std::to_string(k) + " has an end that is not a unit vector");
    }
    if (grid::dot(p.a, p.b) < 0.0) {
      throw std::invalid_argument("site piece " + std::to_string(k) + " is longer than a quarter circle");
    }
  }
  for (std::size_t k = 0; k < in.site_cell_count; ++k) {
    check_site(in.site_cells[k].site, "a site cell");
    grid::require_code(in.site_cells[k].code, in.level);
  }
  for (std::size_t k = 0; k < in.fixed_cell_count; ++k) {
    check_site(in.fixed_cells[k].site, "a fixed cell");
    grid::require_code(in.fixed_cells[k].code, in.level);
  }
  if (rule == Rule::exact && in.piece_count == 0 && in.fixed_cell_count == 0) {
    throw std::invalid_argument("the exact rule needs site pieces (points or arcs) or fixed cells");
  }
  if (rule == Rule::cell && in.site_cell_count == 0 && in.fixed_cell_count == 0) {
    throw std::invalid_argument("the cell rule needs site cells or fixed cells");
  }
}

struct DeviceChoice {
  bool cuda = false;
  int index = 0;
};

DeviceChoice choose_device(const std::string& name) {
  const DeviceSpec spec = parse_device_spec(name);
  if (spec.kind == DeviceSpec::Kind::cpu) return {};
  const int count = cuda::device_count();
  if (spec.kind == DeviceSpec::Kind::automatic) return count > 0 ? DeviceChoice{true, 0} : DeviceChoice{};
  if (count == 0) throw std::runtime_error("device '" + name + "' was asked for, but no usable CUDA GPU was found");
  if (spec.index >= count) {
    throw std::runtime_error("device '" + name + "' was asked for, but there are only " + std::to_string(count) +
                             " CUDA device(s)");
  }
  return {true, spec.index};
}

// --- CPU per-range work ---------------------------------------------------------------------

constexpr std::uint64_t kCpuBlock = 4096;  // cells per OpenMP work item
constexpr std::uint64_t kMinTileCells = 4096;  // below this, tiling is pointless: refuse

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
      // Next cell in code order.
      if (c.col < 2 * c.row) {
        ++c.col;
      } else if (c.row + 1 < grid::rows_per_octant(level)) {
        ++c.row;
        c.col = 0;
      } else {
        ++c.octant;
        c.row = 0;
        c.col = 0;
      }
    }
  }
}

/// Row r (0 .. 2^k - 1, from the apex) of the cells k levels below `cell`, at `level`: the codes
/// [first, last] it holds, and the code of its row's column 0 (for a cell's parity).
struct LeafRow {
  grid::Code first, last, row_start;
};
LeafRow leaf_row(const grid::Cell& cell, int k, std::uint64_t r, int level) {
  const std::uint64_t row = (std::uint64_t{cell.row} << k) + r, rows = std::uint64_t{1} << k;
  const std::uint64_t base = std::uint64_t{cell.col / 2} << (k + 1);
  const grid::Code start = static_cast<std::uint64_t>(cell.octant) * grid::cells_per_octant(level) + row * row;
  return grid::is_up(cell) ? LeafRow{start + base, start + base + 2 * r, start}
                           : LeafRow{start + base + 2 * r + 1, start + base + 2 * rows - 1, start};
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
    if (leaf_row(leaf.cell, k, rows - 1, level).last < first || leaf_row(leaf.cell, k, 0, level).first >= end_code) {
      continue;
    }
    bool ordered = false;  // order made for this leaf
    for (std::uint64_t r = 0; r < rows; ++r) {
      const LeafRow codes = leaf_row(leaf.cell, k, r, level);
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

}  // namespace

// --- candidates -----------------------------------------------------------------------------

std::vector<Piece> make_candidates(const LabelInput& in, Rule rule, int threads_requested) {
  const int threads = thread_count(threads_requested);
  std::vector<Piece> out;
  if (rule == Rule::exact) {
    out.reserve(in.piece_count + in.fixed_cell_count);
    out.resize(in.piece_count);
    const auto n = static_cast<std::int64_t>(in.piece_count);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::int64_t k = 0; k < n; ++k) {
      out[k] = candidate_of(in.pieces[k]);
    }
  } else {
    // One point per distinct (cell, site): duplicates change nothing but the work.
    std::vector<std::pair<grid::Code, std::int32_t>> cells;
    cells.reserve(in.site_cell_count);
    for (std::size_t k = 0; k < in.site_cell_count; ++k) cells.emplace_back(in.site_cells[k].code, in.site_cells[k].site);
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    out.reserve(cells.size() + in.fixed_cell_count);
    for (const auto& [code, site] : cells) out.push_back(make_point_piece(grid::cell_centre_vector(code, in.level), site));
  }
  // Fixed cells in both rules: a point at the cell's centre that wins that cell at distance 0.
  // Under the exact rule it is a point of the polygon site, so it never brings the site nearer
  // than its own geometry would. In quadtree order, as the device build makes them.
  std::vector<FixedCell> ordered;
  const FixedCell* fixed = fixed_cells_in_quadtree_order(in, threads, &ordered);
  for (std::size_t k = 0; k < in.fixed_cell_count; ++k) out.push_back(candidate_of(fixed[k], in.level));
  return out;
}

Best reference_best(const std::vector<Piece>& candidates, grid::Code code, int level) {
  const Vec3 x = grid::cell_centre_vector(code, level);
  Best best = no_best();
  consider_all(best, x, candidates.data(), static_cast<std::int64_t>(candidates.size()));
  return best;
}

// --- the tree -------------------------------------------------------------------------------

namespace {

/// A node of the level being built, with the list its parent kept (the node filters it).
struct Pending {
  grid::Cell cell;
  std::int32_t node;
  std::uint64_t parent_offset;
  std::uint32_t parent_count;
};

/// The fixed cells in code order, for telling a node whose every cell is a fixed cell of one site
/// (each such cell's own fixed point wins it at distance 0, so the node needs no candidates).
class FixedCover {
 public:
  FixedCover(const FixedCell* fixed, std::size_t count, int level) : level_(level) {
    cells_.assign(fixed, fixed + count);
    auto before = [](const FixedCell& a, const FixedCell& b) {
      return a.code != b.code ? a.code < b.code : a.site < b.site;
    };
    // The readers give them in code order already (resolve_claims).
    if (!std::is_sorted(cells_.begin(), cells_.end(), before)) std::sort(cells_.begin(), cells_.end(), before);
    // run_end_[i]: the last code of the run of consecutive codes, one site, from cells_[i] on; a
    // code claimed twice (two polygons) ends every run before it.
    const std::size_t n = cells_.size();
    run_end_.assign(n, 0);
    for (std::size_t i = n; i-- > 0;) {
      const bool twice = (i > 0 && cells_[i - 1].code == cells_[i].code) ||
                         (i + 1 < n && cells_[i + 1].code == cells_[i].code);
      if (twice) {
        run_end_[i] = kNone;
      } else if (i + 1 < n && run_end_[i + 1] != kNone && cells_[i + 1].code == cells_[i].code + 1 &&
                 cells_[i + 1].site == cells_[i].site) {
        run_end_[i] = run_end_[i + 1];
      } else {
        run_end_[i] = cells_[i].code;
      }
    }
  }
  bool empty() const { return cells_.empty(); }

  /// The site whose fixed cells are all the cells below `cell` (of level l), or -1.
  std::int32_t site_covering(const grid::Cell& cell, int l) const {
    const int k = level_ - l;
    std::int32_t site = -1;
    for (std::uint64_t r = 0; r < (std::uint64_t{1} << k); ++r) {
      const LeafRow codes = leaf_row(cell, k, r, level_);
      const auto at = std::lower_bound(cells_.begin(), cells_.end(), codes.first,
                                       [](const FixedCell& f, grid::Code c) { return f.code < c; });
      if (at == cells_.end() || at->code != codes.first) return -1;
      const std::size_t i = static_cast<std::size_t>(at - cells_.begin());
      if (run_end_[i] == kNone || run_end_[i] < codes.last || (site >= 0 && at->site != site)) return -1;
      site = at->site;
    }
    return site;
  }

 private:
  static constexpr grid::Code kNone = ~grid::Code{0};
  int level_;
  std::vector<FixedCell> cells_;
  std::vector<grid::Code> run_end_;
};

/// What the filter decided for one node.
struct Decision {
  std::int32_t kind;        // kUniform, kInternal, or 1 for a list leaf
  std::int32_t site;        // for kUniform
  std::uint64_t offset;     // of its kept list in its thread's buffer
  std::uint32_t count;      // kept candidates
};


}  // namespace

Tree build_tree(const std::vector<Piece>& candidates, int level, bool with_distance, int threads_requested,
                const std::function<void(double fraction)>& level_done, const FixedCell* fixed,
                std::size_t fixed_count) {
  grid::require_level(level);
  if (candidates.empty()) throw std::invalid_argument("build_tree: no candidates");
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("build_tree: more than 2^31 candidates");
  const int threads = thread_count(threads_requested);
  Tree tree;
  tree.level = level;
  // Nodes still mixed at this level become list leaves: their cells test the few candidates
  // left rather than the tree going on down (the last levels hold most of the nodes).
  const int list_level = tree_list_level(level);
  tree.jump_level = tree_jump_level(level);
  tree.nodes.resize(grid::kOctants);

  // QTMV_LABEL_TRACE set: each step's time and size on stderr (for tuning).
  const bool trace = std::getenv("QTMV_LABEL_TRACE") != nullptr;
  const FixedCover cover(fixed, fixed_count, level);
  double t_level = now_seconds();
  // Line runs become groups; the octants start with the runs' top items.
  GroupPlan plan = plan_groups(candidates, threads);
  tree.groups = make_groups(candidates, plan.spans, threads);
  if (trace) {
    std::fprintf(stderr, "trace: host groups %9.3f ms  %zu groups, %zu runs\n", (now_seconds() - t_level) * 1e3,
                 tree.groups.size(), plan.top_items.size());
    t_level = now_seconds();
  }
  const PieceGroup* groups = tree.groups.empty() ? nullptr : tree.groups.data();
  std::vector<std::int32_t> parent_lists = std::move(plan.top_items);
  std::vector<Pending> pending;
  for (int o = 0; o < grid::kOctants; ++o) {
    pending.push_back({grid::Cell{o, 0, 0}, o, 0, static_cast<std::uint32_t>(parent_lists.size())});
  }
  // Candidate evaluations: in the build, and by the cells of list leaves afterwards.
  double weighted_candidates = 0;

  // Each level's nodes are cut into parts, several per thread for balance; a part's kept lists
  // go to its own buffer and are concatenated in order afterwards.
  std::vector<std::vector<std::int32_t>> kept;
  struct Bounds {
    double lb2;
    std::int32_t site;
  };
  std::vector<std::vector<Bounds>> scratch(threads);
  for (int l = 0; l <= level && !pending.empty(); ++l) {
    const std::int64_t n = static_cast<std::int64_t>(pending.size());
    std::vector<Decision> decisions(pending.size());
    const int parts = static_cast<int>(std::min<std::int64_t>(n, std::int64_t{threads} * 16));
    if (static_cast<int>(kept.size()) < parts) kept.resize(parts);
    std::vector<std::uint64_t> leaf_total(parts + 1, 0), internal_total(parts + 1, 0), internal_count(parts + 1, 0),
        leaf_count(parts + 1, 0);
    std::vector<std::pair<std::int64_t, std::int64_t>> chunk(parts);
    const double cells_below = std::ldexp(1.0, 2 * (level - l));
    double evaluations = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : evaluations)
    for (int t = 0; t < parts; ++t) {
      const std::int64_t begin = n * t / parts, end = n * (t + 1) / parts;
      chunk[t] = {begin, end};
      std::vector<std::int32_t>& out = kept[t];
#ifdef _OPENMP
      std::vector<Bounds>& bounds = scratch[omp_get_thread_num()];
#else
      std::vector<Bounds>& bounds = scratch[0];
#endif
      out.clear();
      std::uint64_t leaf_entries = 0, internal_entries = 0, internals = 0, leaves = 0;
      for (std::int64_t q = begin; q < end; ++q) {
        const Pending& p = pending[q];
        evaluations += p.parent_count;
        const Vec3 c = grid::cell_centre_vector(grid::code_of(p.cell, l), l);
        const std::int32_t* list = parent_lists.data() + p.parent_offset;
        Decision dec{0, -1, out.size(), 0};
        bool one_site = true;  // the kept candidates all have site dec.site
        std::int32_t covered = -1;
        if (l == level) {
          // The node is one cell of the level: its label is the best candidate at its centre,
          // settled here once rather than by every look-up.
          std::int32_t winner = -1;
          dec.site = best_of_items(c, list, static_cast<std::int32_t>(p.parent_count), candidates.data(), groups,
                                   &winner).site;
          if (with_distance) out.push_back(winner);
        } else {
          // A node all of whose cells are one site's fixed cells needs no filtering (decide_node).
          covered = cover.empty() ? -1 : cover.site_covering(p.cell, l);
        }
        if (l < level && covered < 0) {
          bounds.resize(p.parent_count);
          double min_ub2 = 1e300;
          for (std::uint32_t k = 0; k < p.parent_count; ++k) {
            double ub2;
            item_bounds(c, list[k], candidates.data(), groups, &bounds[k].lb2, &ub2, &bounds[k].site);
            min_ub2 = std::min(min_ub2, ub2);
          }
          const double radius = node_radius(l, p.cell);
          const double threshold = prune_threshold(min_ub2, radius);
          for (std::uint32_t k = 0; k < p.parent_count; ++k) {
            if (bounds[k].lb2 <= threshold) {
              const std::int32_t site = bounds[k].site;
              if (dec.site < 0) dec.site = site;
              one_site = one_site && site == dec.site;
              const std::int32_t items = kept_items(groups, list[k], radius);
              if (items == 1) {
                out.push_back(list[k]);
              } else {
                for (std::int32_t i = 0; i < items; ++i) out.push_back(split_item(groups, item_group(list[k]), i));
              }
            }
          }
        }
        dec.count = static_cast<std::uint32_t>(out.size() - dec.offset);
        const NodeDecision rule =
            decide_node(l == level, with_distance, l >= list_level, dec.count, one_site, dec.site, covered);
        dec.kind = rule.kind;
        dec.site = rule.site;
        if (dec.kind == kUniform) {
          out.resize(dec.offset);
          dec.count = 0;
          ++leaves;
        } else if (dec.kind == kListLeaf) {
          leaf_entries += dec.count;
          ++leaves;
        } else {
          internal_entries += dec.count;
          ++internals;
        }
        decisions[q] = dec;
      }
      leaf_total[t + 1] = leaf_entries;
      internal_total[t + 1] = internal_entries;
      internal_count[t + 1] = internals;
      leaf_count[t + 1] = leaves;
    }
    for (int t = 0; t < parts; ++t) {
      leaf_total[t + 1] += leaf_total[t];
      internal_total[t + 1] += internal_total[t];
      internal_count[t + 1] += internal_count[t];
      leaf_count[t + 1] += leaf_count[t];
    }
    // Allocate the next level's nodes, lists and pending entries; then fill them in parallel.
    const std::uint64_t lists_base = tree.lists.size();
    const std::size_t nodes_base = tree.nodes.size();
    const std::uint64_t n_internal = internal_count[parts];
    if (nodes_base + 4 * n_internal > 0x7fffffffu || lists_base + leaf_total[parts] > 0x7fffffffu) {
      throw std::runtime_error("the labeller's tree outgrew 2^31 nodes or list entries");
    }
    tree.lists.resize(lists_base + leaf_total[parts]);
    tree.nodes.resize(nodes_base + 4 * n_internal);
    const std::size_t leaves_base = tree.leaves.size();
    tree.leaves.resize(leaves_base + leaf_count[parts]);
    std::vector<std::int32_t> next_lists(internal_total[parts]);
    std::vector<Pending> next(4 * n_internal);
    double weighted = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : weighted)
    for (int t = 0; t < parts; ++t) {
      {
        std::uint64_t leaf_at = lists_base + leaf_total[t], internal_at = internal_total[t];
        std::uint64_t rank = internal_count[t];
        std::size_t leaf_rank = leaves_base + leaf_count[t];
        const std::vector<std::int32_t>& out = kept[t];
        for (std::int64_t q = chunk[t].first; q < chunk[t].second; ++q) {
          const Pending& p = pending[q];
          const Decision& dec = decisions[q];
          TreeNode& node = tree.nodes[p.node];
          if (dec.kind != kInternal) tree.leaves[leaf_rank++] = {p.cell, l, p.node};
          if (dec.kind == kUniform) {
            node = {kUniform, dec.site};
          } else if (dec.kind == kListLeaf) {
            node = {static_cast<std::int32_t>(dec.count), static_cast<std::int32_t>(leaf_at)};
            std::copy(out.begin() + dec.offset, out.begin() + dec.offset + dec.count, tree.lists.begin() + leaf_at);
            leaf_at += dec.count;
            weighted += dec.count * cells_below;
          } else {
            const std::int32_t first_child = static_cast<std::int32_t>(nodes_base + 4 * rank);
            node = {kInternal, first_child};
            std::copy(out.begin() + dec.offset, out.begin() + dec.offset + dec.count, next_lists.begin() + internal_at);
            grid::Cell kids[4];
            grid::children(p.cell, kids);
            for (int k = 0; k < 4; ++k) next[4 * rank + k] = {kids[k], first_child + k, internal_at, dec.count};
            internal_at += dec.count;
            ++rank;
          }
        }
      }
    }
    weighted_candidates += weighted + evaluations;
    parent_lists.swap(next_lists);
    pending.swap(next);
    if (trace) {
      std::fprintf(stderr, "trace: host level %2d %9.3f ms  nodes %lld entries %llu\n", l,
                   (now_seconds() - t_level) * 1e3, static_cast<long long>(n),
                   static_cast<unsigned long long>(evaluations));
      t_level = now_seconds();
    }
    if (level_done) level_done(static_cast<double>(l + 1) / static_cast<double>(level + 1));
  }
  tree.mean_candidates = weighted_candidates / static_cast<double>(grid::cell_count(level));

  // The jump table: where each cell of jump_level starts its walk.
  const std::uint64_t jump_cells = grid::cell_count(tree.jump_level);
  tree.jump.resize(jump_cells);
  const std::int64_t jn = static_cast<std::int64_t>(jump_cells);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < jn; ++k) {
    tree.jump[k] = walk_to_jump_level(tree.nodes.data(), grid::cell_of(static_cast<grid::Code>(k), tree.jump_level),
                                      tree.jump_level);
  }
  return tree;
}

// --- the run --------------------------------------------------------------------------------

MemoryEstimate estimate_output_memory(int level, const LabelOptions& options) {
  grid::require_level(level);
  MemoryEstimate e;
  e.cells = grid::cell_count(level);
  e.bytes_per_cell = sizeof(std::int32_t) + (options.want_distance ? sizeof(float) : 0) + (options.want_boundary ? 1 : 0);
  e.output_bytes = e.cells * e.bytes_per_cell;
  return e;
}

namespace {

/// The host's buffers for one tile of outputs.
struct HostTile {
  std::uint64_t cells;
  std::int32_t* site;
  float* metres;           // null: no distances
  std::uint8_t* boundary;  // null: no flags
};

/// label_cells on a GPU: device tiles as large as its memory allows (smaller ones when an
/// allocation fails), each copied to the host tile by tile and handed to the sink. `done` counts
/// the cells handed over, for the CPU to go on from when the GPU runs out of memory mid-run.
void label_on_gpu(cuda::Labeller& gpu, int device, int level, const LabelOptions& options, const MemoryEstimate& need,
                  const HostTile& host, const std::function<void(const LabelTile&)>& sink, LabelStats& stats,
                  std::uint64_t& done) {
  const std::uint64_t total = need.cells;
  const cuda::DeviceInfo info = cuda::device_info(device);
  const std::uint64_t device_limit =
      options.memory_limit_bytes ? options.memory_limit_bytes : static_cast<std::uint64_t>(info.free_bytes * 0.8);
  std::uint64_t device_tile = std::min<std::uint64_t>(total, device_limit / need.bytes_per_cell);
  if (device_tile < std::min<std::uint64_t>(total, kMinTileCells)) {
    throw std::runtime_error("level " + std::to_string(level) + " needs " + format_gib(double(need.output_bytes)) +
                             " of outputs on the GPU; not even a tile of 4096 cells fits in the " +
                             format_gib(double(device_limit)) + " available");
  }
  for (;;) {
    try {
      gpu.reserve(device_tile, options.want_distance, options.want_boundary);
      break;
    } catch (const cuda::OutOfMemory&) {
      if (device_tile <= kMinTileCells) throw;
      device_tile = std::max<std::uint64_t>(kMinTileCells, device_tile / 4);
      tell(options.messages, Severity::warning,
           "the GPU could not hold the outputs' tile; trying tiles of " + std::to_string(device_tile) + " cells");
    }
  }
  if (device_tile < total) {
    tell(options.messages, Severity::info,
         "level " + std::to_string(level) + " outputs take " + format_gib(double(need.output_bytes)) +
             "; labelling in tiles of " + std::to_string(device_tile) + " cells");
  }
  stats.device_bytes = gpu.device_bytes();
  for (std::uint64_t first = done; first < total; first += device_tile) {
    const std::uint64_t count = std::min(device_tile, total - first);
    stats.label_seconds += gpu.run(first, count, options.want_distance, options.want_boundary) / 1e3;
    ++stats.tiles;
    for (std::uint64_t offset = 0; offset < count; offset += host.cells) {
      const std::uint64_t part = std::min(host.cells, count - offset);
      stats.copy_seconds += gpu.download(offset, part, host.site, host.metres, host.boundary) / 1e3;
      sink({first + offset, part, host.site, host.metres, host.boundary});
      done = first + offset + part;
    }
    report_progress(options.progress, double(first + count) / double(total), "label");
  }
}

}  // namespace

// The candidates' groups halve runs of consecutive candidates of one site (piece_groups.hpp): in
// quadtree order a group of a site's fixed cells is a compact patch, nearly a quadtree node, where
// in rows it was a stretch of rows; near coasts the tree's lists stay short (110m countries, level
// 10: 12 M list entries at the labelling level instead of 238 M).
const FixedCell* fixed_cells_in_quadtree_order(const LabelInput& in, int threads_requested,
                                               std::vector<FixedCell>* storage) {
  const int threads = thread_count(threads_requested);
  struct Keyed {
    std::int32_t site;
    std::uint32_t index;
    std::uint64_t key;
  };
  auto before = [](const Keyed& a, const Keyed& b) {
    return a.site != b.site ? a.site < b.site : a.key != b.key ? a.key < b.key : a.index < b.index;
  };
  const std::int64_t n = static_cast<std::int64_t>(in.fixed_cell_count);
  if (n < 2 || in.fixed_cell_count > 0xffffffffu) return in.fixed_cells;
  std::vector<Keyed> keyed(in.fixed_cell_count);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) {
    const FixedCell& f = in.fixed_cells[k];
    keyed[k] = {f.site, static_cast<std::uint32_t>(k), grid::quadtree_key(grid::cell_of(f.code, in.level), in.level)};
  }
  std::int64_t out_of_order = 0;
#pragma omp parallel for schedule(static) num_threads(threads) reduction(+ : out_of_order)
  for (std::int64_t k = 1; k < n; ++k) out_of_order += before(keyed[k], keyed[k - 1]) ? 1 : 0;
  if (out_of_order == 0) return in.fixed_cells;
#ifdef _OPENMP
  __gnu_parallel::sort(keyed.begin(), keyed.end(), before, __gnu_parallel::default_parallel_tag(threads));
#else
  std::sort(keyed.begin(), keyed.end(), before);
#endif
  storage->resize(keyed.size());
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) (*storage)[k] = in.fixed_cells[keyed[k].index];
  return storage->data();
}

LabelStats label_cells(const LabelInput& input, const LabelOptions& options,
                       const std::function<void(const LabelTile&)>& sink) {
  validate(input, options.rule);
  const int threads = thread_count(options.threads);
  const DeviceChoice device = choose_device(options.device);
  LabelStats stats;
  auto say = [&](const std::string& message) { tell(options.messages, Severity::info, message); };
  auto progress = [&](double fraction, const char* stage) { report_progress(options.progress, fraction, stage); };
  if (device.cuda) {
    const cuda::DeviceInfo info = cuda::device_info(device.index);
    stats.device = "cuda:" + std::to_string(device.index) + " (" + info.name + ")";
  } else {
    stats.device = "cpu (" + std::to_string(threads) + " threads)";
  }

  const double t0 = now_seconds();
  progress(0.0, "prepare");
  // The host's candidates, made when the host needs them: the exact rule's device build makes
  // its own from the input.
  std::vector<Piece> candidates;
  bool candidates_made = false;
  auto host_candidates = [&]() -> const std::vector<Piece>& {
    if (!candidates_made) candidates = make_candidates(input, options.rule, threads);
    candidates_made = true;
    return candidates;
  };
  const double candidate_count = options.rule == Rule::exact
                                     ? static_cast<double>(input.piece_count + input.fixed_cell_count)
                                     : static_cast<double>(host_candidates().size());
  stats.algorithm = options.algorithm;
  if (stats.algorithm == Algorithm::automatic) {
    const double work = static_cast<double>(grid::cell_count(input.level)) * candidate_count;
    stats.algorithm = device.cuda && work <= kBruteWorkLimit ? Algorithm::brute : Algorithm::hier;
  }
  const bool hier = stats.algorithm == Algorithm::hier;
  say("labelling on " + stats.device + (hier ? ", pruned tree (hier)" : ", brute force"));
  // On a GPU the tree is built there (cuda::Labeller's device constructor), inside prepare.
  const bool device_tree = hier && device.cuda && options.tree_on_device;
  std::unique_ptr<cuda::Labeller> gpu_built;
  Tree tree;
  // A GPU that runs out of memory hands the rest of the work to the CPU, with a warning.
  bool on_gpu = device.cuda;
  auto leave_gpu = [&](const cuda::OutOfMemory& e, std::uint64_t from) {
    say("warning: the GPU ran out of memory (" + std::string(e.what()) + "); labelling " +
        (from == 0 ? std::string("on the CPU") : "cells " + std::to_string(from) + " onwards on the CPU") +
        " instead");
    on_gpu = false;
    gpu_built.reset();
    stats.device += ", then cpu (" + std::to_string(threads) + " threads)";
  };
  if (device_tree) {
    try {
      gpu_built = options.rule == Rule::exact
                      ? std::make_unique<cuda::Labeller>(device.index, input, options.want_distance, threads)
                      : std::make_unique<cuda::Labeller>(device.index, host_candidates(), input.level,
                                                         options.want_distance, threads, input.fixed_cells,
                                                         input.fixed_cell_count);
    } catch (const std::length_error&) {
      // Too large for the device build's 32-bit work counts: the host builds it (below).
      gpu_built.reset();
    } catch (const cuda::OutOfMemory& e) {
      leave_gpu(e, 0);
    }
  }
  if (gpu_built) {
    const cuda::TreeInfo info = gpu_built->tree_info();
    stats.tree_nodes = info.nodes;
    stats.tree_list_entries = info.list_entries;
    stats.mean_candidates = info.mean_candidates;
  } else if (hier) {
    // Progress after each level of the build, so that a caller can stop a long build.
    tree = build_tree(host_candidates(), input.level, options.want_distance, threads,
                      [&](double fraction) { progress(fraction, "prepare"); }, input.fixed_cells,
                      input.fixed_cell_count);
    stats.tree_nodes = tree.nodes.size();
    stats.tree_list_entries = tree.lists.size();
    stats.mean_candidates = tree.mean_candidates;
  } else {
    stats.mean_candidates = candidate_count;
  }
  stats.prepare_seconds = now_seconds() - t0;

  const MemoryEstimate need = estimate_output_memory(input.level, options);
  const std::uint64_t total = need.cells;
  // Host tiles are bounded so that a whole-globe run does not double the caller's memory.
  const std::uint64_t host_limit = options.memory_limit_bytes ? options.memory_limit_bytes : host_ram_bytes() / 4;
  std::uint64_t host_tile = std::min<std::uint64_t>(total, std::max<std::uint64_t>(1, host_limit / need.bytes_per_cell));
  host_tile = std::min<std::uint64_t>(host_tile, std::uint64_t{1} << 28);
  if (host_tile < std::min<std::uint64_t>(total, kMinTileCells)) {
    throw std::runtime_error("level " + std::to_string(input.level) + " needs " + format_gib(double(need.output_bytes)) +
                             " of outputs; not even a tile of 4096 cells fits in the " + format_gib(double(host_limit)) +
                             " allowed");
  }
  std::vector<std::int32_t> site(host_tile);
  std::vector<float> metres(options.want_distance ? host_tile : 0);
  std::vector<std::uint8_t> boundary(options.want_boundary ? host_tile : 0);
  float* metres_ptr = options.want_distance ? metres.data() : nullptr;
  std::uint8_t* boundary_ptr = options.want_boundary ? boundary.data() : nullptr;

  std::uint64_t done = 0;  // cells handed to the sink
  if (on_gpu) {
    try {
      if (!gpu_built) {
        gpu_built =
            std::make_unique<cuda::Labeller>(device.index, host_candidates(), hier ? &tree : nullptr, input.level);
      }
      const HostTile host{host_tile, site.data(), metres_ptr, boundary_ptr};
      label_on_gpu(*gpu_built, device.index, input.level, options, need, host, sink, stats, done);
      gpu_built.reset();
      cuda::release_cached_memory(device.index);
      return stats;
    } catch (const cuda::OutOfMemory& e) {
      leave_gpu(e, done);
    }
    if (hier && tree.nodes.empty()) {
      tree = build_tree(host_candidates(), input.level, options.want_distance, threads, {}, input.fixed_cells,
                        input.fixed_cell_count);
    }
  }
  const TreeView tv = tree.view(host_candidates().data());
  for (std::uint64_t first = done; first < total; first += host_tile) {
    const std::uint64_t count = std::min(host_tile, total - first);
    const double start = now_seconds();
    if (hier) {
      cpu_tree_range(tree, tv, first, count, site.data(), metres_ptr, boundary_ptr, threads);
    } else {
      cpu_brute_range(candidates, input.level, first, count, site.data(), metres_ptr, boundary_ptr, threads);
    }
    stats.label_seconds += now_seconds() - start;
    ++stats.tiles;
    sink({first, count, site.data(), metres_ptr, boundary_ptr});
    progress(double(first + count) / double(total), "label");
  }
  return stats;
}

LabelResult label_all(const LabelInput& input, const LabelOptions& options) {
  grid::require_level(input.level);
  const MemoryEstimate need = estimate_output_memory(input.level, options);
  const std::uint64_t ram = host_ram_bytes();
  if (need.output_bytes > ram / 2) {
    throw std::runtime_error("level " + std::to_string(input.level) + " needs " + format_gib(double(need.output_bytes)) +
                             " for its dense outputs, more than half of this host's " + format_gib(double(ram)) +
                             "; use label_cells() to stream tiles instead");
  }
  LabelResult result;
  result.site.resize(need.cells);
  if (options.want_distance) result.distance_m.resize(need.cells);
  if (options.want_boundary) result.boundary.resize(need.cells);
  result.stats = label_cells(input, options, [&](const LabelTile& tile) {
    std::memcpy(result.site.data() + tile.first, tile.site, tile.count * sizeof(std::int32_t));
    if (tile.distance_m) std::memcpy(result.distance_m.data() + tile.first, tile.distance_m, tile.count * sizeof(float));
    if (tile.boundary) std::memcpy(result.boundary.data() + tile.first, tile.boundary, tile.count);
  });
  return result;
}

int cuda_device_count() { return cuda::device_count(); }

}  // namespace qtmv::label
