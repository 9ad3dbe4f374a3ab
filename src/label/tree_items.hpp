// The octants' candidate items (piece_groups.hpp: one per run of a site) in a spatial order, for
// the host's tree build (tree_build.cpp). A node's candidate list is kept as aligned blocks of
// positions in this order (a whole block of any tier, or a tier-0 block with a mask of its
// members) plus loose items (the items of groups that a node split, and the few wide items).
// Each block carries a cap, so that a node keeps or drops a whole block at once when its cap
// shows that every item in it would be, and tests its items one by one otherwise.
//
// Every decision is the one of the plain filter, item by item (item_bounds against
// prune_threshold, the bisector rule of BisectorCut, refine_kept): a cap decides only with a
// margin far above the float64 rounding, and items are tested with the very same float64
// operations. The lists, once put
// back in the candidates' order (SpatialItems::write_in_order), are the plain filter's.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "label/label_math.hpp"
#include "label/piece_groups.hpp"

namespace qtmv::label {

/// A tier-0 block holds 2^kTier0Bits positions (8); a tier-k block 2^(kFanoutBits k) (4^k) tier-0
/// blocks.
constexpr int kTier0Bits = 3;
constexpr int kFanoutBits = 2;

/// Part of a node's list: block `index` of tier `tier`, whole; or, at tier 0, its positions whose
/// bits are set in `mask` (bit k: position 8 index + k).
struct ListBlock {
  std::int32_t index;
  std::uint8_t tier;
  std::uint8_t mask;
};

/// A cap over a block of positions (chords: 2 sin(angle / 2)).
struct ItemBlock {
  Vec3 centre;            ///< a unit vector
  double reach;           ///< every point of every item's pieces and arc lies within it of `centre`
  double reach_rep;       ///< every item's representative point lies within it of `centre`
  double spread;          ///< the largest PieceGroup::spread of its group items (0 when none)
  std::int32_t site_min;  ///< its items' least and greatest site
  std::int32_t site_max;
  std::int32_t points;    ///< 1: every item is a point piece
};

/// A node's bisector rule (label_math.hpp, point_never_nearest): of the point items within its
/// threshold, those wholly beyond the bisector of the nearest one, a (least squared chord, then
/// least item), and a's exact duplicates of sites no lower than a's are dropped as if beyond the
/// threshold. Inactive when no point item is within it.
struct BisectorCut {
  bool active = false;
  std::int32_t item = -1;  ///< a's item (a point piece's item is its piece)
  Vec3 a{0.0, 0.0, 0.0};
  double lb2 = kChord2Infinity;  ///< a's squared chord from the node's centre
  /// No point at a squared chord up to this from the node's centre is beyond a's bisector:
  /// beyond it needs (d(c, b)^2 - d(c, a)^2) / 2 > (r + r^2 / 2) |a - b| >= (r + r^2 / 2)
  /// (d(c, b) - d(c, a)), so d(c, b) + d(c, a) > 2 (r + r^2 / 2) (chords); margins far above the
  /// rounding of the chords (-1: no such shortcut). a's duplicates lie within it but are tested.
  double sure2 = -1.0;
  const Piece* pieces = nullptr;  ///< the candidates, set by settle

  /// Notes a point item within the threshold (squared chord lb2 from the node's centre).
  void note(std::int32_t point_item, const Vec3& p, double point_lb2) {
    if (!active || point_lb2 < lb2 || (point_lb2 == lb2 && point_item < item)) {
      active = true;
      item = point_item;
      a = p;
      lb2 = point_lb2;
    }
  }
  /// Sets sure2, once a is settled, for a node of `radius` (radians); the items are `candidates`'.
  void settle(double radius, const Piece* candidates) {
    pieces = candidates;
    if (!active) return;
    const double base = 2.0 * (radius + 0.5 * radius * radius) - sqrt(lb2) - 1e-7;
    sure2 = base > 0.0 ? base * base * (1.0 - 1e-12) : -1.0;
  }
  /// True when the point item b_item at b (squared chord chord2 from the centre c of a node of
  /// `radius`) is dropped: point_never_nearest(c, radius, a's piece, b's piece), the same bits.
  bool drops(const Vec3& c, double radius, const Vec3& b, double chord2, std::int32_t b_item) const {
    if (!active) return false;
    if (b.x == a.x && b.y == a.y && b.z == a.z) {
      return b_item != item && point_never_nearest(c, radius, pieces[item], pieces[b_item]);
    }
    return chord2 > sure2 && beyond_bisector(c, radius, a, b);
  }
};

/// A node as its filter sees it: centre (unit vector), radius (radians, node_radius), the
/// pruning threshold (squared chord, prune_threshold) and the bisector rule.
struct NodeBounds {
  Vec3 centre;
  double radius;
  double threshold;
  BisectorCut cut;
  bool drops(const Vec3& b, double chord2, std::int32_t item) const {
    return cut.drops(centre, radius, b, chord2, item);
  }
};

/// What a node keeps (written to the given buffers): blocks and loose items, how many items in
/// all, and their least and greatest site.
struct KeptList {
  DefaultInitVector<ListBlock>* blocks;
  DefaultInitVector<std::int32_t>* loose;
  DefaultInitVector<std::int32_t>* points;  ///< a list kept as point positions (tree_point_bins.hpp)
  std::uint64_t count = 0;
  std::int32_t site_min = 0x7fffffff;
  std::int32_t site_max = -1;

  void note_sites(std::int32_t lo, std::int32_t hi) {
    site_min = lo < site_min ? lo : site_min;
    site_max = hi > site_max ? hi : site_max;
  }
  /// Kept items of two sites were seen: no more sites can change one_site().
  bool several_sites() const { return site_min < site_max; }
  /// The plain filter's "all kept items have one site" (true when none is kept), and that site.
  bool one_site() const { return count == 0 || site_min == site_max; }
  std::int32_t site() const { return count == 0 ? -1 : site_min; }
};

/// A parent's list spread out item by item (positions in ascending order, their representative
/// points), which its children's filters share: short lists are filtered so, without caps.
struct FlatList {
  DefaultInitVector<std::int32_t> pos, site;
  DefaultInitVector<double> x, y, z;
  DefaultInitVector<double> lb2;          ///< the node's lower bounds, per item
  DefaultInitVector<std::int32_t> kept;   ///< scratch: the indices of the items a node keeps
  bool points = true;                     ///< every item is a point piece
};

/// A thread's scratch for the filters.
struct FilterScratch {
  std::vector<double> chord2;        ///< per list block: squared chord from the node's centre to its cap's
  std::vector<std::uint64_t> keyed;  ///< write_in_order's
  std::vector<std::int32_t> items;   ///< write_in_order's
  struct Achiever {
    Best best;
    std::int32_t item;
    std::int32_t winner;
  };
  std::vector<Achiever> achievers;   ///< best_in_list's
  /// least_upper_bound's least point item among those it measured (the least of the list's
  /// when its squared chord is the least upper bound).
  BisectorCut nearest_point;
};

class SpatialItems {
 public:
  /// The top items (in candidate order) over `pieces` and `groups`, sorted along a space-filling
  /// curve of their representative points (a piece's first point, a group's arc start); items
  /// wider than kLooseExtent stay loose (loose(), in candidate order). OpenMP, `threads` > 0.
  SpatialItems(const std::vector<std::int32_t>& top_items, const Piece* pieces, const PieceGroup* groups,
               int threads);

  /// Items wider than this (chord, about 64 km) are not placed: their caps would be no use.
  static constexpr double kLooseExtent = 0.01;

  std::int32_t size() const { return static_cast<std::int32_t>(item_.size()); }
  const std::vector<std::int32_t>& loose() const { return loose_; }
  /// Per position: the item, its site, its representative point.
  const std::int32_t* items() const { return item_.data(); }
  const std::int32_t* sites() const { return site_.data(); }
  const Vec3* points() const { return rep_.data(); }
  /// Per position: 1 when its item is a point piece (its bounds are its chord2 to its point).
  const std::uint8_t* point_flags() const { return point_.data(); }

  /// Calls visit(pos) for each position of `list`, in order.
  template <class Visit>
  void for_each_position(const ListBlock* list, std::uint32_t count, Visit visit) const {
    for (std::uint32_t k = 0; k < count; ++k) {
      const ListBlock& b = list[k];
      if (b.tier > 0) {
        const std::int64_t end = block_end(b.tier, b.index);
        for (std::int64_t pos = block_begin(b.tier, b.index); pos < end; ++pos) visit(static_cast<std::int32_t>(pos));
        continue;
      }
      const auto first = static_cast<std::int32_t>(block_begin(0, b.index));
      for (unsigned mask = b.mask; mask != 0; mask &= mask - 1) visit(first + __builtin_ctz(mask));
    }
  }
  /// The whole of the positions as one list block (none when there are no positions).
  DefaultInitVector<ListBlock> whole() const;

  /// The least upper bound (item_bounds' ub2) from x over the positions of `list`, or `best`
  /// when that is less: exactly the minimum, found from the nearest blocks out.
  double least_upper_bound(const Vec3& x, const ListBlock* list, std::uint32_t count, double best,
                           FilterScratch& s) const;

  /// The least point item of `list` (squared chord, then item) within `limit2` (squared chord)
  /// of x noted in cut, found from the nearest blocks out. Needs s.chord2 from least_upper_bound.
  void note_least_point(const Vec3& x, const ListBlock* list, std::uint32_t count, double limit2,
                        const FilterScratch& s, BisectorCut& cut) const;
  /// Notes in cut f's point items within `threshold` (f.lb2: their squared chords).
  void note_flat_points(const FlatList& f, double threshold, BisectorCut& cut) const;

  /// Keeps the positions of `list` that the node keeps (lower bound within its threshold and not
  /// dropped by its bisector rule; a group too loose for the node refined into loose items).
  /// Needs s.chord2 from least_upper_bound for the same node and list.
  void keep(const NodeBounds& node, const ListBlock* list, std::uint32_t count, FilterScratch& s,
            KeptList& out) const;

  /// The positions of `list` (`positions` of them) spread out, with their representative points.
  void flatten(const ListBlock* list, std::uint32_t count, std::uint32_t positions, FlatList& f) const;
  /// The least upper bound over f's items from x, or `best` when that is less; f.lb2 gets the
  /// items' lower bounds.
  double flat_bounds(const Vec3& x, FlatList& f, double best) const;
  /// keep() for f's items, whose lower bounds f.lb2 holds. Only for f.points false: point lists
  /// are kept binned (tree_point_bins.hpp).
  void flat_keep(const NodeBounds& node, FlatList& f, KeptList& out) const;

  /// The best piece for x among the items of `list` (or, when `points` is not null, of the
  /// positions points[0, count)) and `loose` (best_of_items over them in the candidates' order);
  /// *winner (when not null): its index, the first among equals in that order.
  Best best_in_list(const Vec3& x, const ListBlock* list, const std::int32_t* points, std::uint32_t count,
                    const std::int32_t* loose, std::uint32_t loose_count, FilterScratch& s,
                    std::int32_t* winner) const;

  /// The items of `list` (or, when `points` is not null, of the positions points[0, count)) and
  /// `loose` in the candidates' order (the order of their first pieces, as the plain filter keeps
  /// its lists), written to out (`positions` + loose_count entries).
  void write_in_order(const ListBlock* list, const std::int32_t* points, std::uint32_t count, std::uint32_t positions,
                      const std::int32_t* loose, std::uint32_t loose_count, FilterScratch& s,
                      std::int32_t* out) const;

 private:
  std::int64_t block_begin(int tier, std::int64_t index) const { return index << (kTier0Bits + kFanoutBits * tier); }
  std::int64_t block_end(int tier, std::int64_t index) const {
    const std::int64_t e = (index + 1) << (kTier0Bits + kFanoutBits * tier);
    return e < size() ? e : size();
  }
  /// The mask of every position of tier-0 block `index`.
  std::uint8_t full_mask(std::int64_t index) const {
    const std::int64_t left = size() - (index << kTier0Bits);
    return left >= 8 ? 0xff : static_cast<std::uint8_t>((1u << left) - 1);
  }
  /// item_bounds of position pos from x: the same bits.
  void bounds(const Vec3& x, std::int64_t pos, double* lb2, double* ub2) const {
    if (point_[pos]) {
      const Vec3& a = rep_[pos];
      const double dx = x.x - a.x, dy = x.y - a.y, dz = x.z - a.z;
      *lb2 = *ub2 = dx * dx + dy * dy + dz * dz;  // grid::chord2(x, a), as piece_chord2
      return;
    }
    std::int32_t site;
    item_bounds(x, item_[pos], pieces_, groups_, lb2, ub2, &site);
  }
  /// Calls visit(child, mask) for each child block of block `index` of `tier` (> 0): its index
  /// in tier - 1 and the mask of its positions (full: the tier-0 children's own, 0xff above).
  template <class Visit>
  void for_each_child(int tier, std::int64_t index, Visit visit) const {
    const std::int64_t first = index << kFanoutBits;
    const std::int64_t last = std::min<std::int64_t>(first + 4, static_cast<std::int64_t>(tiers_[tier - 1].size()));
    for (std::int64_t c = first; c < last; ++c) visit(c, tier == 1 ? full_mask(c) : std::uint8_t{0xff});
  }
  void keep_split(const NodeBounds& node, std::int64_t pos, KeptList& out) const;
  void nearest_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, double d2, double& best,
                        double& root, BisectorCut& point) const;
  void nearest_point_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, double d2,
                              double limit2, double& root, BisectorCut& cut) const;
  /// Whether no point of the block (cap centre m, reach_rep) is dropped by the node's bisector
  /// rule (1), every one is (2), or neither is certain (0).
  int cap_beyond(const NodeBounds& node, const ItemBlock& b, double d2) const;
  void keep_block(const NodeBounds& node, double root, int tier, std::int64_t index, std::uint8_t mask, double d2,
                  KeptList& out) const;
  void keep_items(const NodeBounds& node, std::int64_t index, std::uint8_t mask, KeptList& out) const;
  void add_items(std::int64_t index, std::uint8_t mask, KeptList& out) const;
  void best_in_block(const Vec3& x, int tier, std::int64_t index, std::uint8_t mask, Best& best,
                     FilterScratch& s) const;
  /// best_in_list's step for one item.
  void consider_item(const Vec3& x, std::int32_t item, Best& best, FilterScratch& s) const;
  /// Fills the positions' arrays from the sorted keys (their low bits: the index among the top
  /// items) and makes the blocks' caps, tier by tier.
  void place(const std::vector<std::int32_t>& top_items, const DefaultInitVector<std::uint64_t>& keyed,
             std::uint64_t index_mask, int threads);

  const Piece* pieces_;
  const PieceGroup* groups_;
  DefaultInitVector<std::int32_t> item_, site_;
  DefaultInitVector<Vec3> rep_;  ///< the representative points
  DefaultInitVector<double> spread_;
  DefaultInitVector<std::uint8_t> point_;  ///< 1: a point piece, whose bounds are its chord2 to its point
  std::vector<DefaultInitVector<ItemBlock>> tiers_;
  std::vector<std::int32_t> loose_;
};

}  // namespace qtmv::label
