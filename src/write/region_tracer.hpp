// Voronoi regions as polygons, traced from the grid's topology.
//
// The cells, drawn in lon/lat as the grid draws them (straight edges between vertices, the
// pole cell of each octant a quadrilateral on latitude +-90), tile the rectangle
// [-180, 180] x [-90, 90] exactly: vertices on octant edges and on the equator are computed to
// the same bits from either side. A site's region is the union of its drawn cells, so its
// boundary is made of the cell edges that separate it from another site, plus the edges on
// the rectangle's border (latitude +-90 and longitude +-180), where every region is cut.
// Those edges are linked into rings instead of uniting millions of triangles.
//
// Rings are counter-clockwise (shells) or clockwise (holes) in lon/lat. Where a region meets
// itself at a single vertex, the walk is cut there into simple rings, so no ring touches
// itself: the pieces come out as separate polygons or holes touching at a point, which is
// valid in the OGC simple-features sense.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "common/huge_page_allocator.hpp"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::write {

using grid::LonLat;

/// One polygon of a region: a counter-clockwise shell and its clockwise holes (degrees), rings
/// not closed (the first vertex is not repeated).
struct RegionPolygon {
  std::vector<LonLat> shell;
  std::vector<std::vector<LonLat>> holes;
};

/// The region of one site: its polygons (empty when the site has no cell).
using Region = std::vector<RegionPolygon>;

/// Which vertices a region's rings keep where they run along a parallel (a row line of the grid, or
/// a pole's line) over several cells.
enum class RingVertices {
  corners,  ///< only the run's ends: one straight lon/lat segment, as planar GIS draws it
  all,      ///< every cell vertex: each ring edge one cell edge, for consumers that read edges as
            ///< geodesics or great circles (PostGIS geography, BigQuery GEOGRAPHY, S2)
};

/// Sees the region edges that are measured (measured_edge: each edge between two sites once, and
/// every border edge) as RegionTracer gathers them, for measures made in the same pass over the
/// outline cells (the regions' areas: region_measures.hpp).
class RegionEdgeObserver {
 public:
  virtual ~RegionEdgeObserver() = default;
  /// One gathering thread's view, used by that thread only.
  class Local {
   public:
    virtual ~Local() = default;
    /// The edge from -> to (degrees) of the region of `site`, on its left; `other` is the site
    /// across it (above `site`), or kBorderEdge.
    virtual void edge(std::int32_t site, const LonLat& from, const LonLat& to, std::int32_t other) = 0;
    /// After the thread's last edge: what the view still holds is handed over (may throw).
    virtual void finish() {}
  };
  /// A view for one more thread (called on that thread; may be called concurrently).
  virtual std::unique_ptr<Local> local() = 0;
};

/// The regions' boundary edges, gathered from the outline cells (label/outline_cells.hpp) and
/// listed per site, from which each region is traced on demand: the edges between sites are
/// edges of boundary cells, the cuts at +-180 and along the poles' lines edges of row ends; a
/// neighbour's site comes from label::NearSearch. Work and memory follow the outline cells,
/// and a writer holds only the regions it is writing.
///
/// The lists hold each outline cell with region edges (its code and which of its drawn edges bound
/// the region) packed in a few bytes (packed_cell_edges.hpp: 1 to 3, where a code took 8), made
/// from a byte per outline cell; a site's edges are drawn again in code order and linked when it
/// is traced.
class RegionTracer {
 public:
  /// Gathers the edges on all cores. `step_done` (may be empty) is called on the calling thread
  /// after each step (gather, bucket) with the fraction done; it may throw to stop.
  /// `vertices`: what the rings keep along parallels (runs along meridians, which are geodesics,
  /// keep their ends only).
  /// `observer` (may be null) sees each measured edge (measured_edge) as it is gathered.
  explicit RegionTracer(const label::Outlines& outlines, RingVertices vertices = RingVertices::corners,
                        const std::function<void(double)>& step_done = {}, RegionEdgeObserver* observer = nullptr);

  std::int32_t site_count() const { return static_cast<std::int32_t>(start_.size()) - 1; }

  /// Host bytes the tracer holds per outline cell (for the run's memory estimate): a mask byte
  /// while it gathers, and a packed entry (mostly 1 to 3 bytes up to level 15, 4 to 5 at the finest levels) with the bucketing's tables
  /// (3.4 measured at 1M random points, level 14).
  static constexpr std::uint64_t kBytesPerOutlineCell = 4;

  /// The region of `site` (0 .. site_count() - 1): its edges linked into rings and grouped into
  /// polygons. Const: callable from several threads at once.
  Region trace(std::int32_t site) const;

  /// One directed boundary edge, with the region on its left: its ends (degrees) and their keys
  /// (grid::cell_polygon_keys: equal exactly where the points are).
  struct Edge {
    LonLat from, to;
    std::uint64_t from_key, to_key;
  };

 private:
  int level_;
  RingVertices vertices_;
  // Every site's outline cells with region edges and their edge masks, site after site, packed
  // (write/packed_cell_edges.hpp): about 1.5 bytes a cell where codes and masks took 8.
  std::vector<std::uint8_t, HugePageAllocator<std::uint8_t>> cells_;
  std::vector<std::size_t> start_;  // site s's bytes: [start_[s], start_[s + 1])
};

/// The outlines of a tile (outlines.range, whole rows) made ready to trace its regions cut at
/// its edges: every cell of the range with a neighbour outside it becomes an outline cell flagged
/// as a boundary cell (its site from site_of), so that visit_region_edges sees its edges across
/// the range's edge as border edges. Its cells per site are the tile's. Not for the boundary
/// cells layer: the flags are the tracer's, not the labels'. The whole level is returned as it is.
label::Outlines with_range_edges(const label::Outlines& outlines);

/// All regions at once (RegionTracer with the rings' corners only, then every site on all
/// cores). Returns
/// outlines.site_count regions. `step_done` as for RegionTracer, and once more when linked.
std::vector<Region> trace_regions(const label::Outlines& outlines, const std::function<void(double)>& step_done = {});

/// The same from dense labels: labels[code] is the site id of cell `code` of `level`
/// (0 .. site_count - 1). Throws std::invalid_argument for a label out of range.
std::vector<Region> trace_regions(int level, const std::int32_t* labels, std::int32_t site_count);

/// Area of a ring in lon/lat (square degrees): positive when counter-clockwise.
double planar_ring_area(const std::vector<LonLat>& ring);

/// Marks a drawn edge on latitude +-90 (the pole cell's fourth side): no cell lies across it.
constexpr int kAcrossPoleLine = -1;

/// The cell as the grid draws it (a counter-clockwise ring, not closed) and, for each edge k
/// (ring[k] -> ring[k + 1]), the grid::NeighbourSlot of the cell across it, or kAcrossPoleLine.
/// Returns the number of corners (3, or 4 for an octant's pole cell).
int drawn_ring(const grid::Cell& c, int level, LonLat ring[grid::kMaxPolygonCorners],
               int across[grid::kMaxPolygonCorners]);

/// drawn_ring's corner count and `across`, without the coordinates.
int drawn_edges(const grid::Cell& c, int across[grid::kMaxPolygonCorners]);

/// The site across a region edge on the lon/lat rectangle's border (latitude +-90, or the cut at
/// +-180): none; the edge bounds its own region only.
constexpr std::int32_t kBorderEdge = -1;

/// Whether the edge from -> to runs along the cut at +-180 (both ends there): a border of the
/// regions' lon/lat rectangle, drawn by the cells on each side at their own side's longitude.
inline bool on_cut(const LonLat& from, const LonLat& to) {
  return std::fabs(from.lon) == 180.0 && std::fabs(to.lon) == 180.0;
}

/// Whether `code` lies in the codes the outlines hold (outlines.range; an unset range, end 0: the
/// whole level). A neighbour outside them is across a tile's edge, where a part's regions are cut.
inline bool holds_code(const label::Outlines& outlines, grid::Code code) {
  return outlines.range.end == 0 || (code >= outlines.range.first && code < outlines.range.end);
}

/// Whether the outlines hold only a part of the level (a tile), whose regions are cut at its edges.
inline bool holds_part(const label::Outlines& outlines) {
  return !holds_code(outlines, 0) || !holds_code(outlines, grid::cell_count(outlines.level) - 1);
}

/// The cells of codes met mostly in increasing order, each row found once for the row's cells
/// (their columns then follow from the codes, without grid::cell_of's square root).
class RowWalk {
 public:
  /// The cell of `code` (any code; codes in increasing order are the fast case).
  grid::Cell cell(grid::Code code, int level) {
    if (code < row_first_ || code >= row_end_) {
      row_ = grid::cell_of(code, level);
      row_first_ = code - row_.col;
      row_end_ = row_first_ + 2 * std::uint64_t{row_.row} + 1;
    }
    return {row_.octant, row_.row, static_cast<std::uint32_t>(code - row_first_)};
  }

 private:
  grid::Cell row_{0, 0, 0};
  grid::Code row_first_ = 1, row_end_ = 0;  // the codes of row_'s row: none yet
};

/// One thread's walk over outline cells in code order (of one octant): their cells (RowWalk) and
/// the sites of the cells near them (label::NearSearch).
class OutlineWalk : public RowWalk {
 public:
  label::NearSearch search;
};

/// An outline cell's corners as drawn (drawn_ring's), computed when first asked for: an edge
/// between two sites is measured from one side only (measured_edge), so half the cells need none.
class DrawnCorners {
 public:
  DrawnCorners(const grid::Cell& cell, int level) : cell_(cell), level_(level) {}
  /// The ends (degrees) of drawn edge e: from(e) -> to(e).
  const LonLat& from(int e) { return corners()[e]; }
  const LonLat& to(int e) {
    const LonLat* ring = corners();  // first: it sets count_
    return ring[e + 1 < count_ ? e + 1 : 0];  // not %: a division per edge
  }

 private:
  const LonLat* corners() {
    if (count_ == 0) count_ = grid::cell_polygon(cell_, level_, ring_);
    return ring_;
  }
  grid::Cell cell_;
  int level_;
  int count_ = 0;  // 0: not computed yet
  LonLat ring_[grid::kMaxPolygonCorners];
};

/// Whether a measure of the regions' edges (their areas, the Voronoi edges' lengths) takes the
/// edge of `site`'s region with `other` across it: every border edge, and an edge between two
/// sites once, from the lower site's side (its measures count for both).
inline bool measured_edge(std::int32_t site, std::int32_t other) { return other == kBorderEdge || other > site; }

/// Visits the edges of the k-th outline cell, as drawn, that bound its site's region (the region
/// on their left): visit(edge, other, corners), `edge` the edge's index in drawn_ring's ring,
/// `other` the site across the edge or kBorderEdge, `corners` the cell's DrawnCorners (its ends:
/// corners.from(edge), corners.to(edge)). Only a boundary cell has a neighbour of another site;
/// of the level's border edges (the poles' lines, the cut at +-180, which run along octant sides)
/// only a row end (the octant's sides, the pole cell) has any. The regions' tracing and their
/// areas both walk the outlines by this one rule. `walk`: the calling thread's, which then visits
/// its cells in code order. Outlines of a part of the level (a tile: outlines.range) cut the
/// regions at its edges: an edge to a cell outside the range is a border edge, seen only where
/// the cell is flagged as a boundary cell (with_range_edges does that).
template <class Visit>
void visit_region_edges(const label::Outlines& outlines, std::size_t k, OutlineWalk& walk, const Visit& visit) {
  const label::OutlineCell& outline = outlines.cells[k];
  const int level = outlines.level;
  const grid::Cell cell = walk.cell(outline.code(), level);
  const bool row_end = label::is_row_end(cell);  // the pole cell (row 0, column 0) is one
  if (!row_end && !outline.boundary()) return;
  DrawnCorners corners(cell, level);
  int across[grid::kMaxPolygonCorners];
  const int count = drawn_edges(cell, across);
  grid::Code nb[3];
  if (outline.boundary()) grid::neighbours(cell, outline.code(), level, nb);
  for (int e = 0; e < count; ++e) {
    if (row_end && (across[e] == kAcrossPoleLine || on_cut(corners.from(e), corners.to(e)))) {
      visit(e, kBorderEdge, corners);
    } else if (outline.boundary()) {
      // The cell across a row line lies a row away in the list; those beside it, next to k.
      const grid::Code code = nb[across[e]];
      if (!holds_code(outlines, code)) {
        visit(e, kBorderEdge, corners);
        continue;
      }
      const std::int32_t other = across[e] == grid::kNeighbourVertical ? walk.search.site(outlines.cells, k, code)
                                                                       : label::site_of_near(outlines.cells, k, code);
      if (other != outline.site) visit(e, other, corners);
    }
  }
}

/// The outline cells in steps for the threads of a pass over them (the regions' edges and their
/// geodesics): step j is the j-th stretch of rows of each of the 8 octants, one octant after
/// another, so that a thread meets an edge's mirror images in the other octants (the same
/// geodesic problem: measure::EdgeSolver::Recent) soon after the edge.
class OctantSteps {
 public:
  explicit OctantSteps(const label::Outlines& outlines);
  std::size_t count() const { return steps_; }
  /// Calls visit(k, walk) for each outline cell k of step `step`, octant by octant in code
  /// order, `walk[octant]` the calling thread's for that octant's cells.
  template <class Visit>
  void visit(std::size_t step, OutlineWalk (&walk)[8], const Visit& visit) const {
    for (std::size_t octant = 0; octant < 8; ++octant) {
      const std::size_t* at = bounds_.data() + octant * (steps_ + 1) + step;
      for (std::size_t k = at[0]; k < at[1]; ++k) visit(k, walk[octant]);
    }
  }

 private:
  std::size_t steps_;
  std::vector<std::size_t> bounds_;  // octant o's step j: outline cells [bounds_[o (steps_ + 1) + j], the next)
};

/// Exact equality and a strict order of lon/lat points (degrees): the grid computes a shared
/// vertex to the same bits from every cell around it.
inline bool same_point(const LonLat& a, const LonLat& b) { return a.lon == b.lon && a.lat == b.lat; }
inline bool point_less(const LonLat& a, const LonLat& b) {
  return a.lon < b.lon || (a.lon == b.lon && a.lat < b.lat);
}

}  // namespace qtmv::write
