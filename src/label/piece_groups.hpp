// Candidates grouped per line run: a hierarchy of bounding "fat arcs" over consecutive pieces of
// one site, so that the tree keeps one entry for a stretch of line instead of hundreds of pieces.
// One body for the CPU and the CUDA kernels (QTMV_HD).
//
// Layout. A run is a maximal range of consecutive candidates (in make_candidates' order) with one
// site (the lines of a site, then its fixed cells: a group across a seam is simply not tight); a
// run of one piece stays a piece. A longer run is cut in halves recursively until at most
// kGroupLeafPieces pieces remain: each cut is a group. The groups of a run are stored in preorder,
// so group g's subtree is [g, g + size) and its first child (if any) is g + 1, its second
// g + 1 + groups[g + 1].size; a group of size 1 (a "bottom" group) holds pieces
// [first, first + count) directly.
//
// Items. The tree's candidate lists hold items: an item >= 0 is a piece index, an item < 0 is the
// group ~item. The octants start with the runs' top items, in candidate order.
//
// Bounds (all chords: 2 sin(angle / 2), squared where the name says chord2). `arc` runs from the
// group's first point A to its last point B (a point at A when the run turns back on itself or
// spans more than 60 degrees). `reach` bounds the distance from every point of every piece of the
// group to `arc`, so for any x (triangle inequality, and chord(a + b) <= chord(a) + chord(b)):
//     d(x, piece) >= d(x, arc) - reach                    (the lower bound of every piece)
// Join each piece's end to the next piece's start by a minor arc (no longer than `gap`, the
// largest such step; 0 for a line): a chain from A to B within reach + gap / 2 of `arc`, each of
// whose points is within gap / 2 of a piece (chords: up to a factor 1 / cos(angle / 4)). When
// that chain is thin and the arc short ("tight"), the nearest-point map from the chain onto `arc`
// is continuous and fixes A and B, so every point of `arc` is within reach + gap / 2 of the
// chain, and
//     min over the group's pieces of d(x, piece) <= d(x, arc) + reach + gap = d(x, arc) + slack.
// A line's run has no gap; fixed cells along a row have a gap of a cell. Otherwise the upper
// bound is the distance to A, a point of the first piece.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "label/label_math.hpp"

namespace qtmv::label {

/// Pieces a bottom group holds at most.
constexpr std::int32_t kGroupLeafPieces = 8;
/// A group that a node keeps is replaced by its subtree (refine_kept) when its spread exceeds
/// this many node radii: its bounds are then too loose to settle the node.
constexpr double kGroupSplit = 1.0;
/// A run is "tight" only when its slack is below this chord (about 2.9 degrees): the continuity
/// argument above needs the chain close to its arc.
constexpr double kTightReach = 0.05;

/// A group as the kernels read it.
struct PieceGroup {
  Piece arc;            ///< A -> B (or a point at A); arc.site is the group's site
  double reach;         ///< chord: every point of the group's pieces lies within it of `arc`
  double slack;         ///< chord: reach + gap (see above)
  double spread;        ///< chord: slack when tight, else the radius about A of the pieces
  std::int32_t first;   ///< first piece
  std::int32_t count;   ///< pieces
  std::int32_t size;    ///< groups in this subtree, itself included (1: a bottom group)
  std::int32_t tight;   ///< 1: the upper bound d(x, arc) + slack holds
};

/// Where a group lies in the candidates and in the preorder, before its bounds are computed.
struct GroupSpan {
  std::int32_t first, count, size;
};

QTMV_HD inline bool is_group_item(std::int32_t item) { return item < 0; }
/// Whether a list item is a point piece (the bisector rule's candidates; never a group).
QTMV_HD inline bool is_point_item(std::int32_t item, const Piece* pieces) {
  return !is_group_item(item) && (pieces[item].flags & kPiecePoint) != 0;
}
QTMV_HD inline std::int32_t group_item(std::int32_t group) { return ~group; }
QTMV_HD inline std::int32_t item_group(std::int32_t item) { return ~item; }

/// Chord of the angle whose sine is s (0 <= s), as 2 s^2 / (1 + sqrt(1 - s^2)) under the root:
/// precise for small angles. s >= 1 gives the quarter-circle chord sqrt(2).
QTMV_HD inline double chord_of_sine(double s) {
  if (s >= 1.0) return sqrt(2.0);
  return sqrt(2.0 * s * s / (1.0 + sqrt(1.0 - s * s)));
}

/// Upper bound (chord) on the distance from any point of piece p to the point A. The farthest
/// point of a minor arc from A is an end while both ends lie within a quarter circle of A;
/// beyond that the bound is the diameter, 2.
QTMV_HD inline double piece_reach_point(const Vec3& a, const Piece& p) {
  const double c = grid::chord2(p.a, a) > grid::chord2(p.b, a) ? grid::chord2(p.a, a) : grid::chord2(p.b, a);
  return c < 1.9 ? sqrt(c) : 2.0;
}

/// Upper bound (chord) on the distance from any point of piece p to the arc (an arc or point
/// piece). When both ends of p project inside the arc, so does all of p (the region is an
/// intersection of two hemispheres), and a point y = (u p.a + v p.b) / |u p.a + v p.b| (u + v = 1)
/// has |y . n| <= max(|p.a . n|, |p.b . n|) / |p.a + p.b| * 2: the sine of its distance to the
/// arc's great circle. Otherwise, or when smaller, the distance to either end of the arc.
QTMV_HD inline double piece_reach(const Piece& arc, const Piece& p) {
  const double to_a = piece_reach_point(arc.a, p);
  if (arc.flags & kPiecePoint) return to_a;
  const double to_b = piece_reach_point(arc.b, p);
  double best = to_a < to_b ? to_a : to_b;
  auto inside = [&](const Vec3& x) {
    return grid::dot(grid::cross(arc.a, x), arc.n) >= 0.0 && grid::dot(grid::cross(x, arc.b), arc.n) >= 0.0;
  };
  if (inside(p.a) && inside(p.b)) {
    const double ta = fabs(grid::dot(p.a, arc.n)), tb = fabs(grid::dot(p.b, arc.n));
    const Vec3 mid = p.a + p.b;
    const double s = (ta > tb ? ta : tb) / sqrt(arc.n2) * 2.0 / sqrt(grid::dot(mid, mid));
    const double c = chord_of_sine(s);
    best = c < best ? c : best;
  }
  return best;
}

/// A group's bounds are maxima over its pieces: order-free, so the host's loop (make_group) and
/// the device's warps give the same bits.
struct GroupTerms {
  double reach = 0.0;  ///< max piece_reach to the arc
  double cap = 0.0;    ///< max piece_reach_point to A
  double gap = 0.0;    ///< max chord from a piece's end to the next piece's start
};

/// The arc of span s: A -> B, or a point at A when B is more than 60 degrees away.
QTMV_HD inline Piece group_arc(const Piece* pieces, const GroupSpan& s) {
  const Piece& head = pieces[s.first];
  const Piece& tail = pieces[s.first + s.count - 1];
  return grid::dot(head.a, tail.b) >= 0.5 ? make_arc_piece(head.a, tail.b, head.site)
                                           : make_point_piece(head.a, head.site);
}

/// Adds piece k of span s to the terms.
QTMV_HD inline void add_group_piece(GroupTerms& t, const Piece& arc, const Piece* pieces, const GroupSpan& s,
                                    std::int32_t k) {
  const Piece& p = pieces[k];
  const double r = piece_reach(arc, p), c = piece_reach_point(pieces[s.first].a, p);
  t.reach = r > t.reach ? r : t.reach;
  t.cap = c > t.cap ? c : t.cap;
  if (k > s.first) {
    const double g = sqrt(grid::chord2(pieces[k - 1].b, p.a));
    t.gap = g > t.gap ? g : t.gap;
  }
}

/// The group of span s from its arc and terms.
QTMV_HD inline PieceGroup finish_group(const Piece& arc, const GroupSpan& s, const GroupTerms& t) {
  PieceGroup g;
  g.arc = arc;
  // Margins for the float64 rounding of the bounds (a few 1e-16) and of the pieces' own chords.
  g.reach = t.reach * (1.0 + 1e-9) + 1e-12;
  const double cap = t.cap * (1.0 + 1e-9) + 1e-12;
  // A join of chord gap has its middle within gap / (2 cos(angle / 4)) of either end: at most
  // 1.0001 gap / 2 below kTightReach.
  g.slack = g.reach + t.gap * (1.0 + 1e-3);
  g.tight = !(arc.flags & kPiecePoint) && g.slack < kTightReach ? 1 : 0;
  g.spread = g.tight ? g.slack : (cap > g.reach ? cap : g.reach);
  g.first = s.first;
  g.count = s.count;
  g.size = s.size;
  return g;
}

/// The group of span s over `pieces` (all of one site): its arc, bounds and tightness.
QTMV_HD inline PieceGroup make_group(const Piece* pieces, const GroupSpan& s) {
  const Piece arc = group_arc(pieces, s);
  GroupTerms t;
  for (std::int32_t k = s.first; k < s.first + s.count; ++k) add_group_piece(t, arc, pieces, s, k);
  return finish_group(arc, s, t);
}

/// Bounds (squared chords) on the distance from x to the nearest point of an item, and its site.
/// A piece's bounds are its distance.
QTMV_HD inline void item_bounds(const Vec3& x, std::int32_t item, const Piece* pieces, const PieceGroup* groups,
                                double* lb2, double* ub2, std::int32_t* site) {
  if (!is_group_item(item)) {
    const Piece& p = pieces[item];
    *lb2 = *ub2 = piece_chord2(x, p);
    *site = p.site;
    return;
  }
  const PieceGroup& g = groups[item_group(item)];
  const double d = sqrt(piece_chord2(x, g.arc));
  const double lo = d - g.reach;
  *lb2 = lo > 0.0 ? lo * lo : 0.0;
  if (g.tight) {
    const double hi = d + g.slack;
    *ub2 = hi * hi;
  } else {
    *ub2 = grid::chord2(x, g.arc.a);
  }
  *site = g.arc.site;
}

/// Whether a node of radius `radius` (radians) that keeps `item` splits it: a group too loose
/// for the node (its bounds could not settle it).
QTMV_HD inline bool splits_item(const PieceGroup* groups, std::int32_t item, double radius) {
  return is_group_item(item) && groups[item_group(item)].spread > kGroupSplit * radius;
}

/// refine_kept's stack: a preorder walk holds at most a subtree's depth + 1 groups, and the
/// groups halve a run down to kGroupLeafPieces (2^31 pieces: 29 levels).
constexpr int kRefineStack = 40;

/// The items a node (centre x, radius `radius`) keeps for `item`, whose lower bound passed the
/// node's threshold (a squared chord): the item itself when it is a piece or a group tight enough
/// for the node (splits_item); else its subtree, depth first in preorder, each group split
/// while looser than the node and dropped when its lower bound exceeds `threshold`, a bottom
/// group's pieces each kept or dropped by its distance. A continent's run, kept near everywhere
/// by one loose bound, so leaves the nodes far from its pieces. Writes the items to `out` when
/// not null; returns their count (0: the item's site is not near the node after all).
QTMV_HD inline std::int32_t refine_kept(const Vec3& x, std::int32_t item, const Piece* pieces,
                                        const PieceGroup* groups, double radius, double threshold,
                                        std::int32_t* out) {
  if (!splits_item(groups, item, radius)) {
    if (out) *out = item;
    return 1;
  }
  std::int32_t count = 0;
  std::int32_t stack[kRefineStack];
  int depth = 0;
  stack[depth++] = item_group(item);
  while (depth > 0) {
    const std::int32_t g = stack[--depth];
    const PieceGroup& group = groups[g];
    if (g != item_group(item)) {  // the root passed its bound already
      const double lo = sqrt(piece_chord2(x, group.arc)) - group.reach;
      if (lo > 0.0 && lo * lo > threshold) continue;
    }
    if (!splits_item(groups, group_item(g), radius)) {
      if (out) out[count] = group_item(g);
      ++count;
    } else if (group.size == 1) {
      for (std::int32_t p = group.first; p < group.first + group.count; ++p) {
        if (piece_chord2(x, pieces[p]) > threshold) continue;
        if (out) out[count] = p;
        ++count;
      }
    } else {
      stack[depth++] = g + 1 + groups[g + 1].size;  // second child, taken after the first's subtree
      stack[depth++] = g + 1;
    }
  }
  return count;
}

/// best_of_items' search of the subtree of group `root` for x: preorder, skipping a subtree whose
/// lower bound exceeds min(best so far, bound) by more than the pruning margin (bound: a squared
/// chord that the best piece's distance cannot exceed). *won gets the index of each piece that
/// improves the best.
QTMV_HD inline void search_group(const Vec3& x, std::int32_t root, const Piece* pieces, const PieceGroup* groups,
                                 double bound, Best& best, std::int32_t& won) {
  const std::int32_t end = root + groups[root].size;
  for (std::int32_t g = root; g < end;) {
    const PieceGroup& group = groups[g];
    const double limit = best.chord2 < bound ? best.chord2 : bound;
    const double lo = sqrt(piece_chord2(x, group.arc)) - group.reach - kPruneMarginRadians;
    if (lo > 0.0 && lo * lo > limit) {
      g += group.size;  // the whole subtree is farther than the best
      continue;
    }
    if (group.size == 1) {
      for (std::int32_t p = group.first; p < group.first + group.count; ++p) {
        const Best before = best;
        consider(best, piece_chord2(x, pieces[p]), pieces[p]);
        if (best.chord2 != before.chord2 || best.rank != before.rank || best.site != before.site) won = p;
      }
    }
    ++g;
  }
}

/// The best piece for x among `count` items, exactly as consider() over all their pieces would
/// pick it: pieces first; then each group's subtree in preorder, skipping a subtree whose lower
/// bound exceeds the best so far (or an item's upper bound) by more than the pruning margin, so
/// that no piece at the best distance, tie included, is skipped. *winner (when not null) gets the
/// index of the piece chosen (the first visited among equals).
QTMV_HD inline Best best_of_items(const Vec3& x, const std::int32_t* items, std::int32_t count, const Piece* pieces,
                                  const PieceGroup* groups, std::int32_t* winner) {
  Best best = no_best();
  std::int32_t won = -1;
  double bound = kChord2Infinity;  // squared chord that the best piece's distance cannot exceed
  bool any_group = false;
  for (std::int32_t k = 0; k < count; ++k) {
    const std::int32_t item = items[k];
    if (is_group_item(item)) {
      any_group = true;
      double lb2, ub2;
      std::int32_t site;
      item_bounds(x, item, pieces, groups, &lb2, &ub2, &site);
      bound = ub2 < bound ? ub2 : bound;
      continue;
    }
    const double d2 = piece_chord2(x, pieces[item]);
    const Best before = best;
    consider(best, d2, pieces[item]);
    if (best.chord2 != before.chord2 || best.rank != before.rank || best.site != before.site) won = item;
  }
  if (any_group) {
    for (std::int32_t k = 0; k < count; ++k) {
      if (is_group_item(items[k])) search_group(x, item_group(items[k]), pieces, groups, bound, best, won);
    }
  }
  if (winner) *winner = won;
  return best;
}

// --- host ------------------------------------------------------------------------------------

/// The groups' preorder spans and the octants' first list.
struct GroupPlan {
  std::vector<GroupSpan> spans;
  std::vector<std::int32_t> top_items;  ///< one per run, in candidate order
};
/// The plan of `count` candidates whose site ids are site_of(0), site_of(1), ... (OpenMP,
/// `threads` > 0 threads); only the sites matter, so the host and the device plan alike from
/// the pieces or from the labeller's input.
GroupPlan plan_groups(std::int64_t count, const std::function<std::int32_t(std::int64_t)>& site_of, int threads);
GroupPlan plan_groups(const std::vector<Piece>& pieces, int threads);

/// make_group for every span (OpenMP, `threads` > 0 threads).
std::vector<PieceGroup> make_groups(const std::vector<Piece>& pieces, const std::vector<GroupSpan>& spans,
                                    int threads);

}  // namespace qtmv::label
