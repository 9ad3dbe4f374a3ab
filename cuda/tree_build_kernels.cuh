// The device tree build's kernels: the same tree as build_tree (src/label/tree_build.cpp), node
// for node and list entry for list entry, one level at a time (the launches and scans:
// tree_build_cuda.cu). Included by tree_build_cuda.cu alone, which launches them (so no
// relocatable device code).
#pragma once

#include <climits>
#include <cstdint>

#include "grid/qtm.hpp"
#include "label/label_math.hpp"
#include "label/label_tree.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label::cuda {

// The same tree as build_tree (tree_build.cpp), node for node and list entry for list entry: one
// level at a time, every (node, parent-list entry) pair is one work item; per node the nearest
// candidate's squared chord (an atomicMin on the float64 bits: the chords are >= 0, so their bit
// patterns order as the values), then the kept entries (d2 <= prune_threshold) are compacted in
// list order by a scan. A point the interval test keeps is dropped where the node lies beyond its
// bisector with the node's nearest point (point_never_nearest): that point's squared chord comes from
// a second atomicMin over the points alone, its item (the least among equals) from a third. The
// nodes' kinds (decide_node, as on the host; a node covered by one site's fixed cells from
// cover_lookup) and offsets and children follow from scans in node order, as the host's parts do.

/// A node of the level being built (see tree_build.cpp's Pending).
struct DevPending {
  grid::Cell cell;
  std::int32_t node;
  std::uint32_t parent_count;
  std::uint64_t parent_offset;
};

/// Per node totals, scanned in node order.
struct LevelSums {
  unsigned long long leaf_entries;      // list entries of list leaves
  unsigned long long internal_entries;  // list entries kept by internal nodes
  unsigned long long internals;         // internal nodes
  __host__ __device__ LevelSums operator+(const LevelSums& o) const {
    return {leaf_entries + o.leaf_entries, internal_entries + o.internal_entries, internals + o.internals};
  }
};
struct AddSums {
  __host__ __device__ LevelSums operator()(const LevelSums& a, const LevelSums& b) const { return a + b; }
};

__global__ void level_init_kernel(const DevPending* pending, std::int32_t n, int level, bool last, Vec3* centre,
                                  double* radius, unsigned long long* start_in, unsigned long long* min_bits,
                                  std::int32_t* site_min, std::int32_t* site_max, unsigned long long* key,
                                  unsigned long long* point_bits, std::int32_t* reference) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  centre[q] = grid::cell_centre_vector(grid::code_of(p.cell, level), level);
  radius[q] = last ? 0.0 : node_radius(level, p.cell);
  start_in[q] = p.parent_count;
  if (q == 0) start_in[n] = 0;
  min_bits[q] = ~0ull;
  point_bits[q] = ~0ull;
  reference[q] = INT_MAX;
  site_min[q] = INT_MAX;
  site_max[q] = INT_MIN;
  key[q] = ~0ull;
}

/// Segmented reductions over a warp whose items are sorted by node (inactive lanes: node -1).
/// Returns true in the lane that holds its node's result.
template <typename T, typename Op>
__device__ inline bool warp_segment_reduce(std::int32_t node, T& value, Op op) {
  const int lane = threadIdx.x & 31;
  for (int off = 1; off < 32; off <<= 1) {
    const T other = __shfl_down_sync(0xffffffffu, value, off);
    const std::int32_t other_node = __shfl_down_sync(0xffffffffu, node, off);
    if (lane + off < 32 && other_node == node) value = op(value, other);
  }
  const std::int32_t prev = __shfl_up_sync(0xffffffffu, node, 1);
  return node >= 0 && (lane == 0 || prev != node);
}

struct MinU64 {
  __device__ unsigned long long operator()(unsigned long long a, unsigned long long b) const { return a < b ? a : b; }
};
struct MinI32 {
  __device__ std::int32_t operator()(std::int32_t a, std::int32_t b) const { return a < b ? a : b; }
};
struct MaxI32 {
  __device__ std::int32_t operator()(std::int32_t a, std::int32_t b) const { return a > b ? a : b; }
};

// The nodes of a level come in groups of four that share one parent list (the four children of
// an internal node; at level 0 the octants 0-3 and 4-7, each with every candidate), so a work
// item is one entry of a group's list, and its piece is read once for the four nodes. Node
// 4 g + c's entries start at start[4 g + c] = 4 start[4 g] / 4 + c * (its list's length).

/// The group holding work item t (start[4 g] <= 4 t < start[4 g + 4]) is owner[t]: each group
/// with items marks its first item, and a running maximum fills the rest.
__global__ void level_owner_kernel(const unsigned long long* start, std::int32_t groups, std::int32_t* heads) {
  const std::int32_t g = blockIdx.x * blockDim.x + threadIdx.x;
  if (g < groups && start[4 * g + 4] > start[4 * g]) heads[start[4 * g] / 4] = g;
}

/// Work item t of a level: the group of four sibling nodes it serves (*group), the position in
/// their shared parent list (*position) and the item found there.
__device__ inline std::int32_t list_item(const DevPending* pending, const std::int32_t* owner,
                                         const unsigned long long* start, unsigned long long t,
                                         const std::int32_t* parent_lists, std::int32_t* group,
                                         unsigned long long* position) {
  const std::int32_t g = owner[t];
  *group = g;
  *position = t - start[4 * g] / 4;
  return parent_lists[pending[4 * g].parent_offset + *position];
}

/// One of the four nodes of a work item's group, with the item's bounds from the node's centre.
struct NodeItem {
  int c;                           ///< the node's place in its group (0-3)
  std::int32_t node;               ///< the node: 4 group + c
  std::int32_t item;               ///< the work item's list item
  unsigned long long position;     ///< its position in the group's parent list
  double lb2, ub2;                 ///< item_bounds from the node's centre (squared chords)
  std::int32_t site;               ///< the item's site
};

/// The start of level_min_kernel and level_keep_kernel: this thread's work item (list_item) and,
/// for each of its group's four nodes in turn, per_node(NodeItem). Returns the group (-1 for a
/// thread past the last item, which visits no node).
template <typename PerNode>
__device__ inline std::int32_t visit_item_nodes(const DevPending* pending, const std::int32_t* owner,
                                                const unsigned long long* start, unsigned long long items,
                                                const std::int32_t* parent_lists, const Piece* pieces,
                                                const PieceGroup* runs, const Vec3* centre, PerNode per_node) {
  const unsigned long long t = static_cast<unsigned long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  std::int32_t g = -1;
  if (t < items) {
    unsigned long long pos;
    const std::int32_t item = list_item(pending, owner, start, t, parent_lists, &g, &pos);
    for (int c = 0; c < 4; ++c) {
      NodeItem n{c, 4 * g + c, item, pos, 0.0, 0.0, 0};
      item_bounds(centre[n.node], item, pieces, runs, &n.lb2, &n.ub2, &n.site);
      per_node(n);
    }
  }
  return g;
}

/// Pass 1: per node the least upper bound of the items' distances (squared chords), and the least
/// of the point items' alone.
__global__ void level_min_kernel(const DevPending* pending, const std::int32_t* owner, const unsigned long long* start,
                                 unsigned long long items, const std::int32_t* parent_lists, const Piece* pieces,
                                 const PieceGroup* runs, const Vec3* centre, unsigned long long* min_bits,
                                 unsigned long long* point_bits) {
  unsigned long long bits[4] = {~0ull, ~0ull, ~0ull, ~0ull}, points[4] = {~0ull, ~0ull, ~0ull, ~0ull};
  const std::int32_t g = visit_item_nodes(pending, owner, start, items, parent_lists, pieces, runs, centre,
                                          [&](const NodeItem& n) {
                                            bits[n.c] = static_cast<unsigned long long>(__double_as_longlong(n.ub2));
                                            if (is_point_item(n.item, pieces)) points[n.c] = bits[n.c];
                                          });
  for (int c = 0; c < 4; ++c) {
    if (warp_segment_reduce(g, bits[c], MinU64{})) atomicMin(&min_bits[4 * g + c], bits[c]);
    if (warp_segment_reduce(g, points[c], MinU64{}) && points[c] != ~0ull) atomicMin(&point_bits[4 * g + c], points[c]);
  }
}

/// Pass 1b: per node its reference point for the bisector rule, the point item nearest its centre
/// (the least item among equals).
__global__ void level_reference_kernel(const DevPending* pending, const std::int32_t* owner,
                                       const unsigned long long* start, unsigned long long items,
                                       const std::int32_t* parent_lists, const Piece* pieces, const PieceGroup* runs,
                                       const Vec3* centre, const unsigned long long* point_bits,
                                       std::int32_t* reference) {
  visit_item_nodes(pending, owner, start, items, parent_lists, pieces, runs, centre, [&](const NodeItem& n) {
    if (is_point_item(n.item, pieces) &&
        static_cast<unsigned long long>(__double_as_longlong(n.lb2)) == point_bits[n.node]) {
      atomicMin(&reference[n.node], n.item);
    }
  });
}

/// Pass 2 (levels above the labelling level): per entry the items it leaves to the node (0, 1,
/// or a loose group's refined subtree: refine_kept), and the kept sites' range per node.
__global__ void level_keep_kernel(const DevPending* pending, const std::int32_t* owner, const unsigned long long* start,
                                  unsigned long long items, const std::int32_t* parent_lists, const Piece* pieces,
                                  const PieceGroup* runs, const Vec3* centre, const double* radius,
                                  const double* threshold, const std::int32_t* reference, unsigned long long* keep,
                                  std::int32_t* site_min, std::int32_t* site_max) {
  std::int32_t lo[4] = {INT_MAX, INT_MAX, INT_MAX, INT_MAX}, hi[4] = {INT_MIN, INT_MIN, INT_MIN, INT_MIN};
  const std::int32_t g = visit_item_nodes(
      pending, owner, start, items, parent_lists, pieces, runs, centre, [&](const NodeItem& n) {
        std::int32_t kept =
            n.lb2 <= threshold[n.node]
                ? refine_kept(centre[n.node], n.item, pieces, runs, radius[n.node], threshold[n.node], nullptr)
                : 0;
        // A kept point beyond its bisector with the reference point is never nearest here.
        const std::int32_t ref = reference[n.node];
        if (kept > 0 && ref != INT_MAX && ref != n.item && is_point_item(n.item, pieces) &&
            point_never_nearest(centre[n.node], radius[n.node], pieces[ref], pieces[n.item])) {
          kept = 0;
        }
        keep[start[n.node] + n.position] = static_cast<unsigned long long>(kept);
        if (kept > 0) lo[n.c] = hi[n.c] = n.site;
      });
  for (int c = 0; c < 4; ++c) {
    const bool lead = warp_segment_reduce(g, lo[c], MinI32{});
    warp_segment_reduce(g, hi[c], MaxI32{});
    if (lead && lo[c] != INT_MAX) {
      atomicMin(&site_min[4 * g + c], lo[c]);
      atomicMax(&site_max[4 * g + c], hi[c]);
    }
  }
}

/// Per node: the pruning threshold.
__global__ void level_threshold_kernel(std::int32_t n, const unsigned long long* min_bits, const double* radius,
                                       double* threshold) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  threshold[q] = prune_threshold(__longlong_as_double(static_cast<long long>(min_bits[q])), radius[q]);
}

/// At the labelling level, per node (one cell): best_of_items over its parent's list, as the host
/// does; key = site << 32 | winning piece.
__global__ void level_settle_kernel(const DevPending* pending, std::int32_t n, const std::int32_t* parent_lists,
                                    const Piece* pieces, const PieceGroup* runs, const Vec3* centre,
                                    unsigned long long* key) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  std::int32_t winner = -1;
  const Best best = best_of_items(centre[q], parent_lists + p.parent_offset, static_cast<std::int32_t>(p.parent_count),
                                  pieces, runs, &winner);
  key[q] = (static_cast<unsigned long long>(best.site) << 32) | static_cast<std::uint32_t>(winner);
}

/// Per node: its kind and counts (decide_node, as build_tree; value: the uniform leaf's site).
__global__ void level_decide_kernel(const DevPending* pending, std::int32_t n, int l, bool last, bool with_distance,
                                    bool list_level_reached, CoverView cover, const unsigned long long* start,
                                    const unsigned long long* keep_pos, const std::int32_t* site_min,
                                    const std::int32_t* site_max, const unsigned long long* key, std::int32_t* kind,
                                    std::int32_t* count, std::int32_t* value, LevelSums* sums_in) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  NodeDecision d;
  std::int32_t c;
  const CoverLookup covered = cover_lookup(cover, pending[q].cell, l);
  if (last) {
    c = with_distance ? 1 : 0;
    d = decide_node(true, with_distance, list_level_reached, static_cast<std::uint32_t>(c), true,
                    static_cast<std::int32_t>(key[q] >> 32), covered.site);
  } else {
    c = static_cast<std::int32_t>(keep_pos[start[q + 1]] - keep_pos[start[q]]);
    const bool one_site = c == 0 || site_min[q] == site_max[q];
    d = decide_node(false, with_distance, list_level_reached, static_cast<std::uint32_t>(c), one_site,
                    c == 0 ? -1 : site_min[q], covered.site, covered.partly, cover.split_partly, covered.claim_site);
  }
  const std::int32_t k = d.kind;
  kind[q] = k;
  count[q] = c;
  value[q] = d.site;
  sums_in[q] = {k == kListLeaf ? static_cast<unsigned long long>(c) : 0ull,
                k == kInternal ? static_cast<unsigned long long>(c) : 0ull, k == kInternal ? 1ull : 0ull};
  if (q == 0) sums_in[n] = {0, 0, 0};
}

/// Per node: its TreeNode, and at the labelling level its winner.
__global__ void level_write_nodes_kernel(const DevPending* pending, std::int32_t n, bool last,
                                         const std::int32_t* kind, const std::int32_t* count,
                                         const std::int32_t* value, const unsigned long long* key,
                                         const LevelSums* offsets, unsigned long long lists_base,
                                         unsigned long long nodes_base, TreeNode* nodes, std::int32_t* lists) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  const LevelSums at = offsets[q];
  if (kind[q] == kUniform) {
    nodes[p.node] = {kUniform, value[q]};
  } else if (kind[q] == kListLeaf) {
    nodes[p.node] = {count[q], static_cast<std::int32_t>(lists_base + at.leaf_entries)};
    if (last) lists[lists_base + at.leaf_entries] = static_cast<std::int32_t>(key[q] & 0xffffffffu);
  } else {
    nodes[p.node] = {kInternal, static_cast<std::int32_t>(nodes_base + 4 * at.internals)};
  }
}

/// Per child of an internal node (thread 4 q + k: child k of node q): its pending entry. A
/// thread per child keeps the writes of the 24-byte entries contiguous across a warp.
__global__ void level_write_children_kernel(const DevPending* pending, std::int32_t n, const std::int32_t* kind,
                                            const std::int32_t* count, const LevelSums* offsets,
                                            unsigned long long nodes_base, DevPending* next) {
  const std::uint64_t t = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= 4 * static_cast<std::uint64_t>(n)) return;
  const auto q = static_cast<std::int32_t>(t >> 2);
  const int k = static_cast<int>(t & 3u);
  if (kind[q] != kInternal) return;
  const LevelSums at = offsets[q];
  grid::Cell kids[4];
  grid::children(pending[q].cell, kids);
  next[4 * at.internals + k] = {kids[k], static_cast<std::int32_t>(nodes_base + 4 * at.internals) + k,
                                static_cast<std::uint32_t>(count[q]), at.internal_entries};
}

/// Per work item, for each of its four nodes: the kept items (the item, or a loose group's
/// refined subtree: refine_kept) to the list leaves' lists or to the next level's parent lists.
__global__ void level_write_lists_kernel(const DevPending* pending, const std::int32_t* owner,
                                         const unsigned long long* start, unsigned long long items,
                                         const std::int32_t* parent_lists, const Piece* pieces,
                                         const PieceGroup* runs, const Vec3* centre, const double* radius,
                                         const double* threshold, const unsigned long long* keep_pos,
                                         const std::int32_t* kind,
                                         const LevelSums* offsets, unsigned long long lists_base, std::int32_t* lists,
                                         std::int32_t* next_lists) {
  const unsigned long long t = static_cast<unsigned long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= items) return;
  std::int32_t g;
  unsigned long long pos;
  const std::int32_t id = list_item(pending, owner, start, t, parent_lists, &g, &pos);
  for (int c = 0; c < 4; ++c) {
    const std::int32_t node = 4 * g + c;
    const unsigned long long e = start[node] + pos;
    const unsigned long long kept = keep_pos[e + 1] - keep_pos[e];
    const std::int32_t k = kind[node];
    if (kept == 0 || k == kUniform) continue;
    const unsigned long long local = keep_pos[e] - keep_pos[start[node]];
    std::int32_t* out = k == kListLeaf ? lists + lists_base + offsets[node].leaf_entries + local
                                           : next_lists + offsets[node].internal_entries + local;
    refine_kept(centre[node], id, pieces, runs, radius[node], threshold[node], out);
  }
}

/// make_group per span, one warp per group (the lanes share its pieces): the same groups as the
/// host's make_groups, since the terms are maxima.
__global__ void make_groups_kernel(const Piece* pieces, const GroupSpan* spans, std::int32_t count,
                                   PieceGroup* groups) {
  const std::uint64_t g = (static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x) >> 5;
  const unsigned lane = threadIdx.x & 31u;
  if (g >= static_cast<std::uint64_t>(count)) return;  // whole warps: count * 32 threads
  const GroupSpan s = spans[g];
  const Piece arc = group_arc(pieces, s);
  GroupTerms t;
  for (std::int32_t k = s.first + static_cast<std::int32_t>(lane); k < s.first + s.count; k += 32) {
    add_group_piece(t, arc, pieces, s, k);
  }
  for (int off = 16; off > 0; off >>= 1) {
    const double reach = __shfl_xor_sync(0xffffffffu, t.reach, off), cap = __shfl_xor_sync(0xffffffffu, t.cap, off);
    const double gap = __shfl_xor_sync(0xffffffffu, t.gap, off);
    t.reach = reach > t.reach ? reach : t.reach;
    t.cap = cap > t.cap ? cap : t.cap;
    t.gap = gap > t.gap ? gap : t.gap;
  }
  if (lane == 0) groups[g] = finish_group(arc, s, t);
}

/// Per cell of the jump level: the node its walk starts from (walk_to_jump_level).
__global__ void jump_kernel(const TreeNode* nodes, int jump_level, std::uint64_t count, JumpEntry* jump) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= count) return;
  jump[k] = walk_to_jump_level(nodes, grid::cell_of(k, jump_level), jump_level);
}

}  // namespace qtmv::label::cuda
