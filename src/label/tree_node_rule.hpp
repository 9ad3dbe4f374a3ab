// What a node of the labeller's tree becomes (uniform leaf, list leaf or internal node): one
// QTMV_HD body for the host build (build_tree, tree_build.cpp) and the device build
// (level_decide_kernel, cuda/tree_build_kernels.cuh), so that the two trees are the same node for node.
// Also both builds' test for a node covered by one site's fixed cells (the cover's key ranges).
#pragma once

#include <cstdint>

#include "grid/qtm_hierarchy.hpp"
#include "grid/qtm_host_device.hpp"
#include "label/label_tree.hpp"

namespace qtmv::label {

/// The decision's kind for a list leaf (its TreeNode then holds the list's length, >= 1).
constexpr std::int32_t kListLeaf = 1;

/// What one node becomes.
struct NodeDecision {
  std::int32_t kind;  ///< kUniform, kListLeaf or kInternal
  std::int32_t site;  ///< for kUniform: the site of every cell below
};

/// The rule for a node of level l, once its candidates are filtered.
///   at_level: l is the labelling level; the node is one cell and `site` its winner's site.
///   list_level_reached: l >= tree_list_level(L).
///   kept_count: the candidates (items) the node kept from its parent's list.
///   one_site: the kept candidates all have site `site` (true when none were kept).
///   covering_site: the site whose fixed cells are all the node's cells, or -1 (only asked
///     above the labelling level; the filtering may then be skipped).
///     At the labelling level: the site that claims the cell, or -1.
///   partly_covered: some of the node's cells are claimed, not all by one site. Such a node is
///     split while `split_partly` (CoverView), else above the list level: claims without
///     candidate points are then reached through covered nodes only. Unless, without distances,
///     its claims and its candidates all have one site (claim_site == site): then it is that
///     site's whole.
QTMV_HD inline NodeDecision decide_node(bool at_level, bool with_distance, bool list_level_reached,
                                        std::uint32_t kept_count, bool one_site, std::int32_t site,
                                        std::int32_t covering_site, bool partly_covered = false,
                                        bool split_partly = false, std::int32_t claim_site = -1) {
  // A claimed cell is its site's at distance 0: no candidate is needed below.
  if (covering_site >= 0) return {kUniform, covering_site};
  // The cell's winner is settled in the build; with distances its list is the winner.
  if (at_level) return {with_distance ? kListLeaf : kUniform, site};
  if (partly_covered && (split_partly || !list_level_reached) &&
      !(one_site && !with_distance && claim_site >= 0 && claim_site == site)) {
    return {kInternal, site};
  }
  if (one_site && !with_distance) return {kUniform, site};
  if ((one_site && kept_count == 1) || (list_level_reached && kept_count <= kMaxLeafList)) {
    return {kListLeaf, site};
  }
  return {kInternal, site};
}

/// The fixed cells and fixed nodes as the builds look them up: ranges of quadtree keys at the
/// labelling level (grid::lowest_owner_partition of them: sorted, disjoint, each key given to the
/// lowest site that claims it, neighbours of one site merged), all arrays of `count` entries.
struct CoverView {
  const std::uint64_t* first;
  const std::uint64_t* last;
  const std::int32_t* site;
  const std::int32_t* owner_run;  ///< per range: the id of its run of ranges of one site (gaps allowed)
  std::uint64_t count;
  int level;  ///< the labelling level L
  /// The claims have no fixed points among the candidates (the readers' fixed nodes): a partly
  /// claimed node is split down to the level, so that every claimed cell lies in a covered leaf.
  /// Otherwise (fixed cells only, each its own fixed point) only above the list level.
  bool split_partly;
};

/// What the cover says of a node.
struct CoverLookup {
  std::int32_t site;  ///< the site whose fixed cells are all the node's cells, or -1
  bool partly;        ///< some but not all of the node's cells are fixed cells of one site
  std::int32_t claim_site;  ///< the one site that claims the node's claimed cells, or -1
};

/// The cover of `cell` (of level l <= L): its cells are the keys [key << 2k, (key + 1) << 2k),
/// k = L - l. The range with the last start at or before the node's last key is the only one
/// that can hold its first key; any range meeting the node starts there or before.
QTMV_HD inline CoverLookup cover_lookup(const CoverView& c, const grid::Cell& cell, int l) {
  if (c.count == 0 || c.first == nullptr) return {-1, false, -1};
  const int shift = 2 * (c.level - l);
  const std::uint64_t first = grid::quadtree_key(cell, l) << shift;
  const std::uint64_t last = first + ((std::uint64_t{1} << shift) - 1);
  std::uint64_t lo = 0, hi = c.count;  // ranges starting at or before `last`: [0, lo)
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    if (c.first[mid] <= last) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  if (lo == 0 || c.last[lo - 1] < first) return {-1, false, -1};
  const std::uint64_t r = lo - 1;
  if (c.first[r] <= first && c.last[r] >= last) return {c.site[r], false, c.site[r]};
  // The first range meeting the node: the first ending at or after `first` (ends ascend too).
  std::uint64_t a = 0, b = r;
  while (a < b) {
    const std::uint64_t mid = a + (b - a) / 2;
    if (c.last[mid] < first) {
      a = mid + 1;
    } else {
      b = mid;
    }
  }
  return {-1, true, c.owner_run[a] == c.owner_run[r] ? c.site[r] : -1};
}

}  // namespace qtmv::label
