// The host's build of the pruned tree (label_tree.hpp), level by level on all cores; the device
// build (cuda/tree_build_cuda.cu) makes the same tree with the same node rule (tree_node_rule.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <utility>
#include <vector>

#include "common/host_info.hpp"
#include "common/trace.hpp"
#include "grid/qtm_checks.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "grid/qtm_topology.hpp"
#include "label/label_engine.hpp"
#include "common/openmp_threads.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label {

namespace {

/// A node of the level being built, with the list its parent kept (the node filters it).
struct Pending {
  grid::Cell cell;
  std::int32_t node;
  std::uint64_t parent_offset;
  std::uint32_t parent_count;
};

/// What the filter decided for one node.
struct Decision {
  std::int32_t kind;        // kUniform, kInternal, or 1 for a list leaf
  std::int32_t site;        // for kUniform
  std::uint64_t offset;     // of its kept list in its thread's buffer
  std::uint32_t count;      // kept candidates
};

/// An item's bounds from a node's centre, as the filter weighs them.
struct Bounds {
  double lb2;
  std::int32_t site;
};

/// One level's filtering: each node's decision, and per part (prefix sums over the parts, parts +
/// 1 entries) the list entries of its leaves and internal nodes and how many of each, which place
/// their lists and children in the next level.
struct LevelFilter {
  int parts = 0;
  std::vector<std::pair<std::int64_t, std::int64_t>> chunk;  ///< each part's nodes
  DefaultInitVector<Decision> decisions;
  std::vector<std::uint64_t> leaf_total, internal_total, internal_count, leaf_count;
  double evaluations = 0;  ///< candidate evaluations of the level
};

/// The host's build, level by level: each level's nodes are filtered (filter_level: the items
/// each keeps, and what it becomes), then the next level's nodes, lists and pending entries are
/// laid out and filled (grow_level).
class TreeBuilder {
 public:
  TreeBuilder(const std::vector<Piece>& candidates, int level, bool with_distance, int threads,
              const CoverView* cover_given, grid::CodeRange focus)
      : candidates_(candidates),
        level_(level),
        with_distance_(with_distance),
        threads_(threads),
        // Nodes still mixed at this level become list leaves: their cells test the few candidates
        // left rather than the tree going on down (the last levels hold most of the nodes).
        list_level_(tree_list_level(level)),
        focus_(focus),
        focused_(focus.end != 0 && !(focus == grid::whole_level(level))),
        cover_(cover_given ? *cover_given : CoverView{nullptr, nullptr, nullptr, nullptr, 0, level, false}) {}

  Tree build(const std::function<void(double fraction)>& level_done, JumpTable jump) {
    tree_.level = level_;
    tree_.nodes.resize(grid::kOctants);
    if (focused_) tree_.focus = focus_;
    // QTMV_TRACE=label: each step's time and size (common/trace.hpp).
    const bool trace = trace_enabled(TraceStage::label);
    double t_level = now_seconds();
    // Line runs become groups; the octants start with the runs' top items.
    GroupPlan plan = plan_groups(candidates_, threads_);
    tree_.groups = make_groups(candidates_, plan.spans, threads_);
    if (trace) {
      trace_printf(TraceStage::label, "host groups %9.3f ms  %zu groups, %zu runs", (now_seconds() - t_level) * 1e3,
                   tree_.groups.size(), plan.top_items.size());
      t_level = now_seconds();
    }
    groups_ = tree_.groups.empty() ? nullptr : tree_.groups.data();
    parent_lists_.assign(plan.top_items.begin(), plan.top_items.end());
    for (int o = 0; o < grid::kOctants; ++o) {
      pending_.push_back({grid::Cell{o, 0, 0}, o, 0, static_cast<std::uint32_t>(parent_lists_.size())});
    }
    // Candidate evaluations: in the build, and by the cells of list leaves afterwards.
    double weighted_candidates = 0;
    scratch_.resize(threads_);
    for (int l = 0; l <= level_ && !pending_.empty(); ++l) {
      const std::int64_t n = static_cast<std::int64_t>(pending_.size());
      const LevelFilter filter = filter_level(l);
      weighted_candidates += grow_level(l, filter) + filter.evaluations;
      if (trace) {
        trace_printf(TraceStage::label, "host level %2d %9.3f ms  nodes %lld entries %llu", l,
                     (now_seconds() - t_level) * 1e3, static_cast<long long>(n),
                     static_cast<unsigned long long>(filter.evaluations));
        t_level = now_seconds();
      }
      if (level_done) level_done(static_cast<double>(l + 1) / static_cast<double>(level_ + 1));
    }
    tree_.mean_candidates = weighted_candidates / static_cast<double>(tree_.labelled_cells());

    const double t_jump = now_seconds();
    fill_jump_table(tree_, jump == JumpTable::full ? tree_jump_level(level_) : tree_outline_jump_level(level_),
                    threads_);
    if (trace) {
      trace_printf(TraceStage::label, "host jump table %9.3f ms  %zu entries of level %d",
                   (now_seconds() - t_jump) * 1e3, tree_.jump.size(), tree_.jump_level);
    }
    return std::move(tree_);
  }

 private:
  /// Whether a node of level l is built: its rows, or those of a node across one of its edges,
  /// meet the focus (see label_engine.hpp).
  bool in_focus(const grid::Cell& cell, int l) const {
    if (!focused_ || grid::rows_meet(focus_, cell, l, level_)) return true;
    grid::Cell across[3];
    grid::neighbours(cell, l, across);
    for (const grid::Cell& other : across) {
      if (grid::rows_meet(focus_, other, l, level_)) return true;
    }
    return false;
  }

  /// Filters the list node p (of level l, centre c) kept by its parent: appends the items it
  /// keeps to `out` and decides what it becomes (decide_node). `bounds`: scratch.
  Decision decide(const Pending& p, int l, const Vec3& c, std::vector<std::int32_t>& out, std::vector<Bounds>& bounds,
                  RadiusStretches& stretches) const {
    const std::int32_t* list = parent_lists_.data() + p.parent_offset;
    Decision dec{0, -1, out.size(), 0};
    bool one_site = true;  // the kept candidates all have site dec.site
    // A node all of whose cells one site claims needs no filtering (decide_node).
    const CoverLookup covered = cover_lookup(cover_, p.cell, l);
    if (l == level_ && covered.site < 0) {
      // The node is one cell of the level: its label is the best candidate at its centre,
      // settled here once rather than by every look-up.
      std::int32_t winner = -1;
      dec.site = best_of_items(c, list, static_cast<std::int32_t>(p.parent_count), candidates_.data(), groups_,
                               &winner).site;
      if (with_distance_) out.push_back(winner);
    }
    if (l < level_ && covered.site < 0) {
      bounds.resize(p.parent_count);
      double min_ub2 = kChord2Infinity;
      for (std::uint32_t k = 0; k < p.parent_count; ++k) {
        double ub2;
        item_bounds(c, list[k], candidates_.data(), groups_, &bounds[k].lb2, &ub2, &bounds[k].site);
        min_ub2 = std::min(min_ub2, ub2);
      }
      const double radius = node_radius(l, p.cell, stretches(l, p.cell.row));
      const double threshold = prune_threshold(min_ub2, radius);
      for (std::uint32_t k = 0; k < p.parent_count; ++k) {
        if (bounds[k].lb2 <= threshold) {
          const std::size_t at = out.size();
          out.resize(at + static_cast<std::size_t>(refine_kept(c, list[k], candidates_.data(), groups_, radius,
                                                               threshold, nullptr)));
          if (out.size() == at) continue;  // none of a loose group's pieces is near the node
          refine_kept(c, list[k], candidates_.data(), groups_, radius, threshold, out.data() + at);
          const std::int32_t site = bounds[k].site;
          if (dec.site < 0) dec.site = site;
          one_site = one_site && site == dec.site;
        }
      }
    }
    dec.count = static_cast<std::uint32_t>(out.size() - dec.offset);
    const NodeDecision rule =
        decide_node(l == level_, with_distance_, l >= list_level_, dec.count, one_site, dec.site, covered.site,
                    covered.partly, cover_.split_partly, covered.claim_site);
    dec.kind = rule.kind;
    dec.site = rule.site;
    if (dec.kind == kUniform) {
      out.resize(dec.offset);
      dec.count = 0;
    }
    return dec;
  }

  /// Decides every pending node of level l. Its nodes are cut into parts, several per thread for
  /// balance; a part's kept lists go to its own buffer (kept_) and are concatenated in order
  /// afterwards.
  LevelFilter filter_level(int l) {
    const std::int64_t n = static_cast<std::int64_t>(pending_.size());
    LevelFilter f;
    f.decisions.resize(pending_.size());  // each written below
    const int parts = static_cast<int>(std::min<std::int64_t>(n, std::int64_t{threads_} * 16));
    f.parts = parts;
    if (static_cast<int>(kept_.size()) < parts) kept_.resize(parts);
    f.leaf_total.assign(parts + 1, 0);
    f.internal_total.assign(parts + 1, 0);
    f.internal_count.assign(parts + 1, 0);
    f.leaf_count.assign(parts + 1, 0);
    f.chunk.resize(parts);
    double evaluations = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_) reduction(+ : evaluations)
    for (int t = 0; t < parts; ++t) {
      const std::int64_t begin = n * t / parts, end = n * (t + 1) / parts;
      f.chunk[t] = {begin, end};
      std::vector<std::int32_t>& out = kept_[t];
#ifdef _OPENMP
      std::vector<Bounds>& bounds = scratch_[omp_get_thread_num()];
#else
      std::vector<Bounds>& bounds = scratch_[0];
#endif
      out.clear();
      std::uint64_t leaf_entries = 0, internal_entries = 0, internals = 0, leaves = 0;
      // A node's four children lie in two rows: their latitudes' sines and their radii's stretch
      // repeat (the same bits as cell_centre_vector and node_radius, as the device build's).
      grid::CentreVectors centres;
      RadiusStretches stretches;
      for (std::int64_t q = begin; q < end; ++q) {
        const Pending& p = pending_[q];
        Decision dec{kUniform, 0, out.size(), 0};
        if (in_focus(p.cell, l)) {
          evaluations += p.parent_count;
          dec = decide(p, l, centres(p.cell, l), out, bounds, stretches);
        }
        if (dec.kind == kUniform) {
          ++leaves;
        } else if (dec.kind == kListLeaf) {
          leaf_entries += dec.count;
          ++leaves;
        } else {
          internal_entries += dec.count;
          ++internals;
        }
        f.decisions[q] = dec;
      }
      f.leaf_total[t + 1] = leaf_entries;
      f.internal_total[t + 1] = internal_entries;
      f.internal_count[t + 1] = internals;
      f.leaf_count[t + 1] = leaves;
    }
    for (int t = 0; t < parts; ++t) {
      f.leaf_total[t + 1] += f.leaf_total[t];
      f.internal_total[t + 1] += f.internal_total[t];
      f.internal_count[t + 1] += f.internal_count[t];
      f.leaf_count[t + 1] += f.leaf_count[t];
    }
    f.evaluations = evaluations;
    return f;
  }

  /// Allocates the next level's nodes, lists and pending entries after level l's filter; then
  /// fills them in parallel. Returns the candidate evaluations of level l's list leaves' cells.
  double grow_level(int l, const LevelFilter& f) {
    const int parts = f.parts;
    const double cells_below = std::ldexp(1.0, 2 * (level_ - l));
    const std::uint64_t lists_base = tree_.lists.size();
    const std::size_t nodes_base = tree_.nodes.size();
    const std::uint64_t n_internal = f.internal_count[parts];
    if (nodes_base + 4 * n_internal > 0x7fffffffu || lists_base + f.leaf_total[parts] > 0x7fffffffu) {
      throw std::runtime_error("the labeller's tree outgrew 2^31 nodes or list entries");
    }
    tree_.lists.resize(lists_base + f.leaf_total[parts]);
    tree_.nodes.resize(nodes_base + 4 * n_internal);
    const std::size_t leaves_base = tree_.leaves.size();
    tree_.leaves.resize(leaves_base + f.leaf_count[parts]);
    DefaultInitVector<std::int32_t> next_lists(f.internal_total[parts]);  // every entry written below
    DefaultInitVector<Pending> next(4 * n_internal);
    double weighted = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_) reduction(+ : weighted)
    for (int t = 0; t < parts; ++t) {
      {
        std::uint64_t leaf_at = lists_base + f.leaf_total[t], internal_at = f.internal_total[t];
        std::uint64_t rank = f.internal_count[t];
        std::size_t leaf_rank = leaves_base + f.leaf_count[t];
        const std::vector<std::int32_t>& out = kept_[t];
        for (std::int64_t q = f.chunk[t].first; q < f.chunk[t].second; ++q) {
          const Pending& p = pending_[q];
          const Decision& dec = f.decisions[q];
          TreeNode& node = tree_.nodes[p.node];
          if (dec.kind != kInternal) tree_.leaves[leaf_rank++] = {p.cell, l, p.node};
          if (dec.kind == kUniform) {
            node = {kUniform, dec.site};
          } else if (dec.kind == kListLeaf) {
            node = {static_cast<std::int32_t>(dec.count), static_cast<std::int32_t>(leaf_at)};
            std::copy(out.begin() + dec.offset, out.begin() + dec.offset + dec.count, tree_.lists.begin() + leaf_at);
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
    parent_lists_.swap(next_lists);
    pending_.swap(next);
    return weighted;
  }

  const std::vector<Piece>& candidates_;
  const int level_;
  const bool with_distance_;
  const int threads_;
  const int list_level_;
  const grid::CodeRange focus_;
  const bool focused_;
  const CoverView cover_;
  Tree tree_;
  const PieceGroup* groups_ = nullptr;
  DefaultInitVector<std::int32_t> parent_lists_;  ///< the lists the pending nodes' parents kept
  DefaultInitVector<Pending> pending_;            ///< the nodes of the level being built
  std::vector<std::vector<std::int32_t>> kept_;   ///< per part: the lists its nodes keep
  std::vector<std::vector<Bounds>> scratch_;      ///< per thread: decide's bounds
};

}  // namespace

Tree build_tree(const std::vector<Piece>& candidates, int level, bool with_distance, int threads_requested,
                const std::function<void(double fraction)>& level_done, const CoverView* cover_given,
                JumpTable jump, grid::CodeRange focus) {
  grid::require_level(level);
  if (candidates.empty()) throw std::invalid_argument("build_tree: no candidates");
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("build_tree: more than 2^31 candidates");
  return TreeBuilder(candidates, level, with_distance, thread_count(threads_requested), cover_given, focus)
      .build(level_done, jump);
}

void fill_jump_table(Tree& tree, int jump_level, int threads_requested) {
  if (tree.jump_level == jump_level && !tree.jump.empty()) return;
  const int threads = thread_count(threads_requested);
  // Where each cell of jump_level starts its walk.
  tree.jump_level = jump_level;
  const std::uint64_t jump_cells = grid::cell_count(jump_level);
  tree.jump.resize(jump_cells);
  const std::int64_t jn = static_cast<std::int64_t>(jump_cells);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < jn; ++k) {
    tree.jump[k] = walk_to_jump_level(tree.nodes.data(), grid::cell_of(static_cast<grid::Code>(k), jump_level), jump_level);
  }
}

}  // namespace qtmv::label
