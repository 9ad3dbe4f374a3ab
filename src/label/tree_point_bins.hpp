// Lists of point items (each a point piece: its bounds are its squared chord) kept binned by
// their squared chord from the list's owner, a node of the host's tree build (tree_build.cpp).
// The owner's four children filter the list: by the triangle inequality (chords are distances in
// space) a child whose centre lies within `delta` of the owner's sees the points of a bin at
// least as far as the bin's inner edge less delta, so it stops its nearest-point search at the
// first bin beyond the nearest point found, and passes over the bins beyond its threshold. Each
// kept point is tested as the plain filter tests it (its squared chord against the threshold,
// the same float64 operations); the bins only spare the points that lie beyond, with a margin far
// above the rounding. A child keeps its own list binned about its own centre.
#pragma once

#include <cstdint>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "label/tree_items.hpp"

namespace qtmv::label {

constexpr int kPointBins = 16;

/// The bins of a list: bin b holds the points at squared chords in [b, b + 1) threshold /
/// kPointBins from `centre` (the last also those at the threshold itself).
struct PointBins {
  Vec3 centre;
  double threshold;
  std::uint32_t first[kPointBins + 1];  ///< bin b: entries [first[b], first[b + 1]) of the list
};

/// A thread's scratch for the binned filters.
struct PointScratch {
  DefaultInitVector<double> chord2;  ///< per list entry: its squared chord from the node's centre
  int searched = 0;                  ///< the bins whose chord2 binned_least wrote
  DefaultInitVector<std::int32_t> pos;    ///< the node's kept points, before they are binned
  DefaultInitVector<double> kept_chord2;  ///< and their squared chords from its centre
  DefaultInitVector<std::uint8_t> bin;    ///< emit_binned's: each kept point's bin
  std::int32_t least_pos = -1;            ///< binned_keep's least kept point (then least item), or -1
  double least_chord2 = 0.0;              ///< and its squared chord
};

/// Lists of at most this many points are kept plain (unbinned): their children test them all.
constexpr std::size_t kPlainPoints = 32;

/// The least squared chord from x to the `count` points `points` (positions of `items`) binned by
/// `bins` (or plain: null), or `best` when that is less.
double binned_least(const SpatialItems& items, const Vec3& x, const std::int32_t* points, std::uint32_t count,
                    const PointBins* bins, double best, PointScratch& s);

/// The points of the same list that the node (centre x, as binned_least's) keeps, into s.pos and
/// s.kept_chord2, and the least of them (then least item) into s.least_pos.
void binned_keep(const SpatialItems& items, const NodeBounds& node, const std::int32_t* points, std::uint32_t count,
                 const PointBins* bins, PointScratch& s);

/// binned_keep for a list spread out (f.points: every item a point piece) whose squared chords
/// from the node's centre f.lb2 holds.
void flat_points_keep(const FlatList& f, const NodeBounds& node, PointScratch& s);

/// The `blocks` (count of them) that a node (centre x) kept, into s.pos and s.kept_chord2 when
/// every item in them is a point piece (returns true), so that they can be kept binned.
bool points_of_blocks(const SpatialItems& items, const Vec3& x, const ListBlock* blocks, std::uint32_t count,
                      PointScratch& s);

/// Notes binned_keep's least kept point in cut.
void note_kept_points(const SpatialItems& items, const PointScratch& s, BisectorCut& cut);
/// Drops from s.pos (and s.kept_chord2) the points that the node's bisector rule drops.
void drop_beyond_bisector(const SpatialItems& items, const NodeBounds& node, PointScratch& s);

/// The points s.pos (squared chords s.kept_chord2 from the node's centre) appended to
/// *out.points, their count and sites noted in out: binned about the node, their bins in *bins
/// (returns true), unless they are few (at most kPlainPoints) or `bins` is null (a node that cannot
/// have children).
bool emit_points(const SpatialItems& items, const NodeBounds& node, PointScratch& s, KeptList& out, PointBins* bins);

}  // namespace qtmv::label
