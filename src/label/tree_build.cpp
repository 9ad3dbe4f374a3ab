// The host's build of the pruned tree (label_tree.hpp), level by level on all cores: long lists
// block by block (tree_items.hpp), short lists of points by bins (tree_point_bins.hpp); the
// device build (cuda/tree_build_cuda.cu) makes the same tree with the same node rule
// (tree_node_rule.hpp). A node keeps its parent's items within its distance threshold
// (prune_threshold) less the point items wholly beyond the bisector with its nearest point item
// or its exact duplicates of sites no lower (BisectorCut, point_never_nearest): every path below
// finds that point first, then filters.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/config_option.hpp"
#include "common/host_info.hpp"
#include "common/trace.hpp"
#include "grid/qtm_checks.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "grid/qtm_topology.hpp"
#include "label/label_engine.hpp"
#include "common/openmp_threads.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_items.hpp"
#include "label/tree_point_bins.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label {

namespace {

/// A node's candidate list in the buffers of one part of the level above: blocks of positions
/// (tree_items.hpp) or point positions (tree_point_bins.hpp), and loose items; `items` in all.
struct ListRef {
  std::uint64_t at;        ///< the first block, or point
  std::uint64_t loose_at;
  std::uint32_t length;    ///< blocks, or points
  std::uint32_t loose;
  std::uint32_t items;
  std::int32_t part;
  std::int32_t bins;       ///< points: their PointBins in the part, or -1 (plain, or a leaf's)
  bool points;             ///< the positions are points (binned when bins >= 0); else blocks
};

/// A node of the level being built, with the list its parent kept (the node filters it).
struct Pending {
  grid::Cell cell;
  std::int32_t node;
  ListRef parent;
};

/// What the filter decided for one node; `kept` lies in its part's buffers.
struct Decision {
  std::int32_t kind;  // kUniform, kInternal, or 1 for a list leaf
  std::int32_t site;  // for kUniform
  ListRef kept;
};

/// One level's filtering: each node's decision, and per part (prefix sums over the parts, parts +
/// 1 entries) the list entries of its leaves and how many internal nodes and leaves it has,
/// which place its leaves' lists and its nodes' children in the tree.
struct LevelFilter {
  int parts = 0;
  std::vector<std::pair<std::int64_t, std::int64_t>> chunk;  ///< each part's nodes
  DefaultInitVector<Decision> decisions;
  std::vector<std::uint64_t> leaf_total, internal_count, leaf_count;
  double evaluations = 0;  ///< candidate evaluations of the level
};

/// A part's kept lists: its internal nodes' lists are their children's parent lists, read where
/// they are (no copy) while the next level is filtered. Aligned to a cache line: the parts'
/// vectors grow on different threads.
struct alignas(64) PartLists {
  DefaultInitVector<ListBlock> blocks;
  DefaultInitVector<std::int32_t> loose;
  DefaultInitVector<std::int32_t> points;
  std::vector<PointBins> bins;
};

/// A thread's scratch (aligned to a cache line, as PartLists).
struct alignas(64) Scratch {
  std::vector<double> lb2;         ///< the loose items' lower bounds
  std::vector<std::int32_t> site;  ///< and sites
  FilterScratch filter;            ///< the blocks' filter's
  PointScratch points;             ///< the point bins' filter's
  FlatList flat;                   ///< a short parent list spread out, for its children
  const ListBlock* flat_of = nullptr;  ///< whose: its blocks, and how many
  std::uint32_t flat_blocks = 0;
};

/// The form of a node's kept list: blocks of positions, or point positions, plain or binned.
enum class ListForm { blocks, points, binned };

/// Lists of at most this many items are filtered item by item (kept as points when they are
/// points, else spread out for their nodes' children); longer ones (the coarse levels') block by
/// block.
constexpr std::uint32_t kFlatList = 4096;

/// The host's build, level by level: each level's nodes are filtered (filter_level: the items
/// each keeps, and what it becomes), then the next level's nodes, lists and pending entries are
/// laid out and filled (grow_level). The octants' items are placed in a spatial order
/// (SpatialItems), so that a node's list is blocks of positions that nodes filter block by
/// block, or, once short, point positions binned about the node; a list leaf's list is put back
/// in the candidates' order, the plain filter's.
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
    items_ = std::make_unique<SpatialItems>(plan.top_items, candidates_.data(), groups_, threads_);
    if (trace) {
      trace_printf(TraceStage::label, "host items %9.3f ms  %d placed, %zu loose", (now_seconds() - t_level) * 1e3,
                   items_->size(), items_->loose().size());
      t_level = now_seconds();
    }
    // The octants' list: every item, in one part.
    parts_[1].resize(1);
    parts_[1][0].blocks = items_->whole();
    parts_[1][0].loose.assign(items_->loose().begin(), items_->loose().end());
    const ListRef all{0, 0, static_cast<std::uint32_t>(parts_[1][0].blocks.size()),
                      static_cast<std::uint32_t>(parts_[1][0].loose.size()),
                      static_cast<std::uint32_t>(plan.top_items.size()), 0, -1, false};
    for (int o = 0; o < grid::kOctants; ++o) pending_.push_back({grid::Cell{o, 0, 0}, o, all});
    // Candidate evaluations: in the build, and by the cells of list leaves afterwards.
    double weighted_candidates = 0;
    scratch_.resize(threads_);
    for (int l = 0; l <= level_ && !pending_.empty(); ++l) {
      const std::int64_t n = static_cast<std::int64_t>(pending_.size());
      const LevelFilter& filter = filter_level(l);
      weighted_candidates += grow_level(l, filter) + filter.evaluations;
      if (trace) {
        trace_printf(TraceStage::label, "host level %2d %9.3f ms  nodes %lld entries %llu", l,
                     (now_seconds() - t_level) * 1e3, static_cast<long long>(n),
                     static_cast<unsigned long long>(filter.evaluations));
        t_level = now_seconds();
      }
      if (level_done) level_done(static_cast<double>(l + 1) / static_cast<double>(level_ + 1));
      if (l < level_) check_level_fits(l + 1);
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

  /// Notes in node.cut the loose point items within node.threshold (their bounds in s.lb2).
  void note_loose_points(const std::int32_t* loose, std::uint32_t count, const Scratch& s, NodeBounds& node) const {
    for (std::uint32_t k = 0; k < count; ++k) {
      if (s.lb2[k] <= node.threshold && is_point_item(loose[k], candidates_.data())) {
        node.cut.note(loose[k], candidates_[loose[k]].a, s.lb2[k]);
      }
    }
  }

  /// Filters the parent's list of p (a node of level l < L, centre c): the items it keeps go to
  /// `kept` (item_bounds against prune_threshold, the bisector rule of its nearest point item:
  /// BisectorCut, refine_kept), as blocks or as points (binned: their bins in *bins).
  ListForm filter(const Pending& p, int l, const Vec3& c, const CoverLookup& covered, Scratch& s,
                  RadiusStretches& stretches, KeptList& kept, PointBins* bins) const {
    const PartLists& from = parent_part(p);
    const std::int32_t* loose = from.loose.data() + p.parent.loose_at;
    const std::size_t loose_at = kept.loose->size();
    double min_ub2 = kChord2Infinity;
    s.lb2.resize(p.parent.loose);
    s.site.resize(p.parent.loose);
    for (std::uint32_t k = 0; k < p.parent.loose; ++k) {
      double ub2;
      item_bounds(c, loose[k], candidates_.data(), groups_, &s.lb2[k], &ub2, &s.site[k]);
      min_ub2 = std::min(min_ub2, ub2);
    }
    const double radius = node_radius(l, p.cell, stretches(l, p.cell.row));
    bool points = false;
    NodeBounds node{c, radius, 0.0, {}};
    if (p.parent.points) {
      const std::int32_t* list = from.points.data() + p.parent.at;
      const PointBins* parent_bins = p.parent.bins >= 0 ? &from.bins[p.parent.bins] : nullptr;
      node.threshold =
          prune_threshold(binned_least(*items_, c, list, p.parent.length, parent_bins, min_ub2, s.points), radius);
      binned_keep(*items_, node, list, p.parent.length, parent_bins, s.points);
      note_loose_points(loose, p.parent.loose, s, node);
      note_kept_points(*items_, s.points, node.cut);
      node.cut.settle(radius, candidates_.data());
      drop_beyond_bisector(*items_, node, s.points);
      points = true;
    } else {
      const ListBlock* blocks = from.blocks.data() + p.parent.at;
      const bool flat = p.parent.items <= kFlatList;
      if (flat && (s.flat_of != blocks || s.flat_blocks != p.parent.length)) {
        items_->flatten(blocks, p.parent.length, p.parent.items - p.parent.loose, s.flat);
        s.flat_of = blocks;  // a sibling's list, spread out already, serves again
        s.flat_blocks = p.parent.length;
      }
      min_ub2 = flat ? items_->flat_bounds(c, s.flat, min_ub2)
                     : items_->least_upper_bound(c, blocks, p.parent.length, min_ub2, s.filter);
      node.threshold = prune_threshold(min_ub2, radius);
      note_loose_points(loose, p.parent.loose, s, node);
      if (flat) {
        items_->note_flat_points(s.flat, node.threshold, node.cut);
      } else if (s.filter.nearest_point.active && s.filter.nearest_point.lb2 == min_ub2) {
        // The least upper bound is a point's: the list's least point, found with its equals.
        const BisectorCut& near = s.filter.nearest_point;
        node.cut.note(near.item, near.a, near.lb2);
      } else {
        items_->note_least_point(c, blocks, p.parent.length, node.threshold, s.filter, node.cut);
      }
      node.cut.settle(radius, candidates_.data());
      if (flat && s.flat.points) {
        flat_points_keep(s.flat, node, s.points);
        drop_beyond_bisector(*items_, node, s.points);
        points = true;
      } else if (flat) {
        items_->flat_keep(node, s.flat, kept);
      } else {
        const std::size_t blocks_at = kept.blocks->size();
        items_->keep(node, blocks, p.parent.length, s.filter, kept);
        // A short list of points goes on as points (its children need not spread it out).
        if (kept.count <= kFlatList && kept.loose->size() == loose_at &&
            points_of_blocks(*items_, c, kept.blocks->data() + blocks_at,
                             static_cast<std::uint32_t>(kept.blocks->size() - blocks_at), s.points)) {
          kept.blocks->resize(blocks_at);
          kept.count = 0;
          points = true;
        }
      }
    }
    ListForm form = ListForm::blocks;
    if (points) {
      // A node that keeps few enough at the list level has no children (decide_node): its list
      // needs no bins.
      const bool leaf = l >= list_level_ && p.parent.loose == 0 && s.points.pos.size() <= kMaxLeafList &&
                        !(covered.partly && cover_.split_partly);
      form = emit_points(*items_, node, s.points, kept, leaf ? nullptr : bins) ? ListForm::binned : ListForm::points;
    }
    for (std::uint32_t k = 0; k < p.parent.loose; ++k) {
      if (!(s.lb2[k] <= node.threshold)) continue;
      const bool point = is_point_item(loose[k], candidates_.data());
      if (point && node.drops(candidates_[loose[k]].a, s.lb2[k], loose[k])) continue;
      const std::size_t at = kept.loose->size();
      const std::int32_t n = refine_kept(c, loose[k], candidates_.data(), groups_, radius, node.threshold, nullptr);
      if (n == 0) continue;  // none of a loose group's pieces is near the node
      kept.loose->resize(at + static_cast<std::size_t>(n));
      refine_kept(c, loose[k], candidates_.data(), groups_, radius, node.threshold, kept.loose->data() + at);
      kept.count += static_cast<std::uint64_t>(n);
      kept.note_sites(s.site[k], s.site[k]);
    }
    return form;
  }

  /// Filters the parent's list of p (of level l, centre c), appending the items it keeps to
  /// `out`, and decides what it becomes (decide_node).
  Decision decide(const Pending& p, int l, const Vec3& c, PartLists& out, std::int32_t part, Scratch& s,
                  RadiusStretches& stretches) const {
    const std::size_t blocks_at = out.blocks.size(), points_at = out.points.size(), loose_at = out.loose.size();
    KeptList kept{&out.blocks, &out.loose, &out.points};
    bool one_site = true;
    ListForm form = ListForm::blocks;
    std::int32_t site = -1;
    PointBins bins;
    // A node all of whose cells one site claims needs no filtering (decide_node).
    const CoverLookup covered = cover_lookup(cover_, p.cell, l);
    if (l == level_ && covered.site < 0) {
      // The node is one cell of the level: its label is the best candidate at its centre,
      // settled here once rather than by every look-up.
      std::int32_t winner = -1;
      const PartLists& from = parent_part(p);
      site = items_->best_in_list(c, p.parent.points ? nullptr : from.blocks.data() + p.parent.at,
                                  p.parent.points ? from.points.data() + p.parent.at : nullptr, p.parent.length,
                                  from.loose.data() + p.parent.loose_at, p.parent.loose, s.filter,
                                  with_distance_ ? &winner : nullptr).site;
      if (with_distance_) {
        out.loose.push_back(winner);
        kept.count = 1;
      }
    }
    if (l < level_ && covered.site < 0) {
      form = filter(p, l, c, covered, s, stretches, kept, &bins);
      one_site = kept.one_site();
      site = kept.site();
    }
    if (kept.count > 0x7fffffffu) throw std::runtime_error("the labeller's tree: a list of 2^31 candidates");
    const bool points = form != ListForm::blocks;
    Decision dec{0, -1, {points ? points_at : blocks_at, loose_at,
                         static_cast<std::uint32_t>(points ? out.points.size() - points_at : out.blocks.size() - blocks_at),
                         static_cast<std::uint32_t>(out.loose.size() - loose_at), static_cast<std::uint32_t>(kept.count),
                         part, -1, points}};
    const NodeDecision rule = decide_node(l == level_, with_distance_, l >= list_level_, dec.kept.items, one_site, site,
                                          covered.site, covered.partly, cover_.split_partly, covered.claim_site);
    dec.kind = rule.kind;
    dec.site = rule.site;
    if (dec.kind == kUniform) {
      out.blocks.resize(blocks_at);
      out.points.resize(points_at);
      out.loose.resize(loose_at);
      dec.kept = {blocks_at, loose_at, 0, 0, 0, part, -1, false};
    } else if (dec.kind == kInternal && form == ListForm::binned) {
      dec.kept.bins = static_cast<std::int32_t>(out.bins.size());
      out.bins.push_back(bins);
    }
    return dec;
  }

  const PartLists& parent_part(const Pending& p) const { return (*parent_parts_)[p.parent.part]; }

  /// Throws, rather than the kernel ending the process, before level l's filter when the lists
  /// its nodes may keep (each at most its parent's: 4 bytes an entry) and their children's
  /// pending entries cannot fit in half the memory the host can still give. Sites in tight
  /// clusters far from most nodes (lines, polygons: the bisector rule prunes points only) keep
  /// whole clusters in every node, four times as many entries a level.
  void check_level_fits(int l) const {
    std::uint64_t entries = 0;
    for (const Pending& p : pending_) entries += p.parent.items;
    const std::uint64_t bytes = 4 * entries + 4 * pending_.size() * (sizeof(Pending) + sizeof(Decision));
    // The tests make the host small (QTMV_FAULT_AVAILABLE_MEMORY, bytes).
    const std::string small = fault_switch("QTMV_FAULT_AVAILABLE_MEMORY");
    const std::uint64_t available = small.empty() ? available_memory_bytes() : std::stoull(small);
    if (bytes <= available / 2) return;
    throw std::runtime_error("the labeller's tree would need up to " + format_gib(double(bytes)) + " at level " +
                             std::to_string(l) + " of " + std::to_string(level_) + " (" + std::to_string(entries) +
                             " candidate entries in " + std::to_string(pending_.size()) +
                             " nodes), more than half the " + format_gib(double(available)) +
                             " this host has free: sites in tight clusters far from most cells (see MEMORY AND "
                             "WORK in the manual); choose a lower -level");
  }

  Scratch& thread_scratch() {
#ifdef _OPENMP
    return scratch_[omp_get_thread_num()];
#else
    return scratch_[0];
#endif
  }

  /// Decides every pending node of level l. Its nodes are cut into parts, several per thread for
  /// balance; a part's kept lists go to its own buffers, where the next level reads them.
  const LevelFilter& filter_level(int l) {
    const std::int64_t n = static_cast<std::int64_t>(pending_.size());
    LevelFilter& f = filter_;  // its arrays' room kept from level to level
    f.decisions.resize(pending_.size());  // each written below
    const int parts = static_cast<int>(std::min<std::int64_t>(n, std::int64_t{threads_} * 16));
    f.parts = parts;
    // The parts' buffers of two levels before are reused (fresh pages cost the kernel's zeroing).
    std::vector<PartLists>& kept = parts_[l & 1];
    parent_parts_ = &parts_[(l + 1) & 1];
    if (static_cast<int>(kept.size()) < parts) kept.resize(parts);
    for (std::vector<std::uint64_t>* v : {&f.leaf_total, &f.internal_count, &f.leaf_count}) v->assign(parts + 1, 0);
    f.chunk.resize(parts);
    for (Scratch& s : scratch_) s.flat_of = nullptr;
    double evaluations = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_) reduction(+ : evaluations)
    for (int t = 0; t < parts; ++t) {
      const std::int64_t begin = n * t / parts, end = n * (t + 1) / parts;
      f.chunk[t] = {begin, end};
      PartLists& out = kept[t];
      Scratch& scratch = thread_scratch();
      out.blocks.clear();
      out.loose.clear();
      out.points.clear();
      out.bins.clear();
      std::uint64_t leaf_entries = 0, internals = 0, leaves = 0;
      // A node's four children lie in two rows: their latitudes' sines and their radii's stretch
      // repeat (the same bits as cell_centre_vector and node_radius, as the device build's).
      grid::CentreVectors centres;
      RadiusStretches stretches;
      for (std::int64_t q = begin; q < end; ++q) {
        const Pending& p = pending_[q];
        Decision dec{kUniform, 0, {out.blocks.size(), out.loose.size(), 0, 0, 0, t, -1, false}};
        if (in_focus(p.cell, l)) {
          evaluations += p.parent.items;
          dec = decide(p, l, centres(p.cell, l), out, t, scratch, stretches);
        }
        if (dec.kind == kInternal) {
          ++internals;
        } else {
          if (dec.kind == kListLeaf) leaf_entries += dec.kept.items;
          ++leaves;
        }
        f.decisions[q] = dec;
      }
      f.leaf_total[t + 1] = leaf_entries;
      f.internal_count[t + 1] = internals;
      f.leaf_count[t + 1] = leaves;
    }
    for (int t = 0; t < parts; ++t) {
      f.leaf_total[t + 1] += f.leaf_total[t];
      f.internal_count[t + 1] += f.internal_count[t];
      f.leaf_count[t + 1] += f.leaf_count[t];
    }
    f.evaluations = evaluations;
    return f;
  }

  /// Sizes v to n entries, its old ones of no use (not copied when it grows).
  template <class T>
  static void reuse(DefaultInitVector<T>& v, std::size_t n) {
    if (n > v.capacity()) v.clear();
    v.resize(n);
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
    // Every entry written below; the array of two levels before is reused.
    DefaultInitVector<Pending>& next = spare_pending_;
    reuse(next, 4 * n_internal);
    double weighted = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_) reduction(+ : weighted)
    for (int t = 0; t < parts; ++t) {
      std::uint64_t leaf_at = lists_base + f.leaf_total[t];
      std::uint64_t rank = f.internal_count[t];
      std::size_t leaf_rank = leaves_base + f.leaf_count[t];
      const PartLists& out = parts_[l & 1][t];
      Scratch& scratch = thread_scratch();
      for (std::int64_t q = f.chunk[t].first; q < f.chunk[t].second; ++q) {
        const Pending& p = pending_[q];
        const Decision& dec = f.decisions[q];
        const ListRef& kept = dec.kept;
        TreeNode& node = tree_.nodes[p.node];
        if (dec.kind != kInternal) tree_.leaves[leaf_rank++] = {p.cell, l, p.node};
        if (dec.kind == kUniform) {
          node = {kUniform, dec.site};
        } else if (dec.kind == kListLeaf) {
          node = {static_cast<std::int32_t>(kept.items), static_cast<std::int32_t>(leaf_at)};
          items_->write_in_order(kept.points ? nullptr : out.blocks.data() + kept.at,
                                 kept.points ? out.points.data() + kept.at : nullptr, kept.length,
                                 kept.items - kept.loose, out.loose.data() + kept.loose_at, kept.loose, scratch.filter,
                                 tree_.lists.data() + leaf_at);
          leaf_at += kept.items;
          weighted += kept.items * cells_below;
        } else {
          const std::int32_t first_child = static_cast<std::int32_t>(nodes_base + 4 * rank);
          node = {kInternal, first_child};
          grid::Cell kids[4];
          grid::children(p.cell, kids);
          for (int k = 0; k < 4; ++k) next[4 * rank + k] = {kids[k], first_child + k, kept};
          ++rank;
        }
      }
    }
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
  std::unique_ptr<SpatialItems> items_;           ///< the octants' items in a spatial order
  LevelFilter filter_;                            ///< the level's decisions
  DefaultInitVector<Pending> pending_;            ///< the nodes of the level being built
  DefaultInitVector<Pending> spare_pending_;      ///< the array of the level before, for the next
  /// Per part, the lists its nodes keep: level l's in parts_[l & 1], read by level l + 1 (the
  /// octants' list in parts_[1]).
  std::vector<PartLists> parts_[2];
  const std::vector<PartLists>* parent_parts_ = nullptr;
  std::vector<Scratch> scratch_;                  ///< per thread
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

DefaultInitVector<JumpEntry> make_jump_table(const TreeNode* nodes, int jump_level, int threads_requested) {
  const int threads = thread_count(threads_requested);
  // Where each cell of jump_level starts its walk.
  const std::uint64_t jump_cells = grid::cell_count(jump_level);
  DefaultInitVector<JumpEntry> jump(jump_cells);
  const std::int64_t jn = static_cast<std::int64_t>(jump_cells);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < jn; ++k) {
    jump[k] = walk_to_jump_level(nodes, grid::cell_of(static_cast<grid::Code>(k), jump_level), jump_level);
  }
  return jump;
}

void fill_jump_table(Tree& tree, int jump_level, int threads_requested) {
  if (tree.jump_level == jump_level && !tree.jump.empty()) return;
  tree.jump_level = jump_level;
  tree.jump = make_jump_table(tree.nodes.data(), jump_level, threads_requested);
}

}  // namespace qtmv::label
