// What a node of the labeller's tree becomes (uniform leaf, list leaf or internal node): one
// QTMV_HD body for the host build (build_tree, labeller.cpp) and the device build
// (level_decide_kernel, cuda/label_cuda.cu), so that the two trees are the same node for node.
// Also the device's test for a node covered by one site's fixed cells, over the fixed cells'
// sorted quadtree keys (the host's FixedCover answers the same question from rows of codes).
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
QTMV_HD inline NodeDecision decide_node(bool at_level, bool with_distance, bool list_level_reached,
                                        std::uint32_t kept_count, bool one_site, std::int32_t site,
                                        std::int32_t covering_site) {
  // The cell's winner is settled in the build; with distances its list is the winner.
  if (at_level) return {with_distance ? kListLeaf : kUniform, site};
  // Each fixed cell's own point wins it at distance 0: no candidate is needed below.
  if (covering_site >= 0) return {kUniform, covering_site};
  if (one_site && !with_distance) return {kUniform, site};
  if ((one_site && kept_count == 1) || (list_level_reached && kept_count <= kMaxLeafList)) {
    return {kListLeaf, site};
  }
  return {kInternal, site};
}

/// The fixed cells as fixed_cover_site looks them up, all arrays of `count` entries:
///   key: their quadtree keys (grid::quadtree_key at `level`), ascending;
///   site: the key's site, or -1 for a key claimed twice (two polygons: no node holding it is
///     covered, as on the host);
///   run: the id of the key's run, a stretch of consecutive keys of one site none claimed twice
///     (a key claimed twice is a run of its own).
struct FixedCoverView {
  const std::uint64_t* key;
  const std::int32_t* site;
  const std::int32_t* run;
  std::uint64_t count;
  int level;  ///< the labelling level L
};

/// The site whose fixed cells are all the cells below `cell` (of level l <= L), or -1. The node's
/// cells are the 4^k keys [key << 2k, (key + 1) << 2k), k = L - l: all there iff the first is
/// present and the 4^k-th entry from it lies in its run (a run's keys go up by one).
QTMV_HD inline std::int32_t fixed_cover_site(const FixedCoverView& f, const grid::Cell& cell, int l) {
  const int k = f.level - l;
  const std::uint64_t cells = std::uint64_t{1} << (2 * k);
  if (cells > f.count) return -1;
  const std::uint64_t first = grid::quadtree_key(cell, l) << (2 * k);
  std::uint64_t lo = 0, hi = f.count;  // lower bound of `first`
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    if (f.key[mid] < first) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  if (lo + cells > f.count || f.key[lo] != first || f.site[lo] < 0) return -1;
  return f.run[lo] == f.run[lo + cells - 1] ? f.site[lo] : -1;
}

/// Per entry i of the ascending keys (and their sites): fixed_cover_site's site (-1: claimed
/// twice) and whether a new run starts here. The device computes these in parallel, then the
/// run ids as an inclusive sum of the starts.
QTMV_HD inline void fixed_cover_entry(const std::uint64_t* key, const std::int32_t* site, std::uint64_t count,
                                      std::uint64_t i, std::int32_t* cover_site, std::int32_t* run_starts) {
  auto twice = [&](std::uint64_t j) {
    return (j > 0 && key[j - 1] == key[j]) || (j + 1 < count && key[j + 1] == key[j]);
  };
  const bool dup = twice(i);
  *cover_site = dup ? -1 : site[i];
  *run_starts = i == 0 || dup || twice(i - 1) || key[i] != key[i - 1] + 1 || site[i] != site[i - 1];
}

}  // namespace qtmv::label
