// Sets of cells as ranges of quadtree keys (qtm_hierarchy.hpp): the cells below a node of level
// l are the keys [key << 2 (L - l), (key + 1) << 2 (L - l)) of the level L, so a polygon's
// interior given as nodes ("a cover") and single cells are both ranges. Host code only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <queue>
#include <utility>
#include <vector>

#include "qtm_hierarchy.hpp"

namespace qtmv::grid {

/// Keys [first, last] (inclusive, at one level) held by `owner`.
struct KeyRange {
  std::uint64_t first;
  std::uint64_t last;
  std::int32_t owner;
};

/// The keys, at `level`, of the cells below `node` (of node_level <= level).
inline KeyRange node_key_range(const Cell& node, int node_level, int level, std::int32_t owner) {
  const int shift = 2 * (level - node_level);
  const std::uint64_t first = quadtree_key(node, node_level) << shift;
  return {first, first + ((std::uint64_t{1} << shift) - 1), owner};
}

/// The order lowest_owner_partition_of_sorted takes: by first key, then owner.
inline bool key_range_before(const KeyRange& a, const KeyRange& b) {
  return a.first != b.first ? a.first < b.first : a.owner < b.owner;
}

/// The keys covered by `ranges` (sorted by key_range_before; overlaps allowed), each given to
/// the lowest owner that holds it: sorted, disjoint ranges, neighbours of one owner merged (so a
/// set of keys is held by one owner iff one range holds them all).
template <class Alloc>
std::vector<KeyRange> lowest_owner_partition_of_sorted(const std::vector<KeyRange, Alloc>& ranges) {
  std::vector<KeyRange> out;
  out.reserve(ranges.size());
  auto emit = [&](std::uint64_t first, std::uint64_t last, std::int32_t owner) {
    if (!out.empty() && out.back().owner == owner && out.back().last + 1 == first) {
      out.back().last = last;
    } else {
      out.push_back({first, last, owner});
    }
  };
  // Ranges come in runs, each range of a run starting within the ones before it. A run of one
  // (most of them: a polygon's cover is disjoint, polygons seldom overlap) is emitted as it is;
  // a longer one is swept with the ranges open at `pos`, lowest owner on top (ranges that ended
  // are dropped when on top).
  using Open = std::pair<std::int32_t, std::uint64_t>;  // owner, last
  std::priority_queue<Open, std::vector<Open>, std::greater<Open>> open;
  for (std::size_t run = 0; run < ranges.size();) {
    std::size_t run_end = run + 1;
    for (std::uint64_t reach = ranges[run].last; run_end < ranges.size() && ranges[run_end].first <= reach; ++run_end) {
      reach = std::max(reach, ranges[run_end].last);
    }
    if (run_end == run + 1) {
      emit(ranges[run].first, ranges[run].last, ranges[run].owner);
      run = run_end;
      continue;
    }
    std::size_t next = run;
    std::uint64_t pos = 0;
    while (next < run_end || !open.empty()) {
      if (open.empty()) pos = std::max(pos, ranges[next].first);
      while (next < run_end && ranges[next].first <= pos) {
        if (ranges[next].last >= pos) open.push({ranges[next].owner, ranges[next].last});
        ++next;
      }
      while (!open.empty() && open.top().second < pos) open.pop();
      if (open.empty()) continue;
      // The lowest owner holds on until it ends or a range opens (which may hold a lower one).
      std::uint64_t end = open.top().second;
      if (next < run_end && ranges[next].first - 1 < end) end = ranges[next].first - 1;
      emit(pos, end, open.top().first);
      if (end == ~std::uint64_t{0}) break;
      pos = end + 1;
    }
    open = {};
    run = run_end;
  }
  return out;
}

/// The same for ranges in any order.
inline std::vector<KeyRange> lowest_owner_partition(std::vector<KeyRange> ranges) {
  std::sort(ranges.begin(), ranges.end(), key_range_before);
  return lowest_owner_partition_of_sorted(ranges);
}

/// Calls visit(node, node_level) for the fewest nodes whose cells are exactly the keys
/// [first, last] at `level` (the aligned blocks of 4^k keys, as an address range splits into
/// network prefixes).
template <class Visit>
void for_each_node_of_range(std::uint64_t first, std::uint64_t last, int level, Visit&& visit) {
  std::uint64_t key = first;
  while (key <= last) {
    int k = 0;  // the largest block of 4^k keys aligned at `key` within the range
    while (k < level && (key & ((std::uint64_t{4} << (2 * k)) - 1)) == 0 &&
           key + ((std::uint64_t{4} << (2 * k)) - 1) <= last) {
      ++k;
    }
    const int node_level = level - k;
    const std::uint64_t node_key = key >> (2 * k);
    visit(cell_of_quadtree_key(node_key, node_level), node_level);
    const std::uint64_t next = key + (std::uint64_t{1} << (2 * k));
    if (next == 0) break;
    key = next;
  }
}

}  // namespace qtmv::grid
