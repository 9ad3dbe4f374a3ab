// Polygon fill: the cells whose centres lie inside a polygon and outside its holes.
//
// Scanlines: the cell centres of a level lie on 4 * 2^L - 1 parallels (the up and down centres
// of every row, mirrored in the south), and on each parallel their longitudes are arithmetic
// progressions per octant. Each ring edge is cut with the parallels it spans (half-open in
// latitude), each ring's crossings on a parallel pair up into inside intervals, intervals are
// brought into [-180, 180] and combined by parity over all rings (even-odd), and the centres
// inside each interval are enumerated directly. Work: crossings + cells filled, no per-cell
// point-in-polygon test.
//
// Edges are straight in lon/lat, with longitudes unwrapped (see unwrap_longitudes). A ring that
// winds once around the globe is closed through the pole on its side of the equator (the side
// of its mean latitude). With rings that do not cross +-180 this gives exactly the centres that
// GEOS finds within the polygon in flat lon/lat (centres on the boundary are outside).
#pragma once

#include <cstdint>
#include <vector>

#include "grid/qtm.hpp"

namespace qtmv::sites {

/// One ring to fill: vertices (degrees, unwrapped longitudes, closed: last repeats first up to the
/// winding) and its winding (see UnwrappedPath).
struct FillRing {
  std::vector<grid::LonLat> vertices;
  int winding = 0;
};

class PolygonFiller {
 public:
  explicit PolygonFiller(int level);

  /// Appends to `cells` the codes of the cells whose centres are inside the polygon made of
  /// `rings` (outer ring and holes, combined even-odd), each once, in no particular order.
  void fill(const std::vector<FillRing>& rings, std::vector<grid::Code>& cells) const;

  /// A quadtree node: its code at its level.
  struct CoverNode {
    grid::Code code;
    int level;
  };
  /// The same cells as fill(), as a cover: the largest quadtree nodes all of whose cells' centres
  /// are inside (to `nodes`, levels below the filler's) and the single cells left (to `cells`),
  /// each cell in exactly one of them. Work follows the rings: nodes are split only where their
  /// centres are mixed, row by row (the ends of a row's up and down centres decide), from the
  /// octants down; no interior cell is visited.
  void cover(const std::vector<FillRing>& rings, std::vector<grid::Code>& cells, std::vector<CoverNode>& nodes) const;

  /// An inside interval of one scanline (an index into the filler's scanlines, ascending
  /// latitude): longitudes (lo, hi), degrees in [-180, 180].
  struct Interval {
    std::uint32_t scan;
    double lo, hi;
  };

  int level() const { return level_; }

 private:
  struct Scanline {
    double lat;          // latitude of the centres (degrees)
    int first_octant;    // 0 (north) or 4 (south)
    std::uint32_t row;
    bool up;
  };
  void emit_interval(const Scanline& line, double lo, double hi, std::vector<grid::Code>& cells) const;
  /// The rings' inside intervals, by scanline then longitude, disjoint (even-odd over all rings).
  std::vector<Interval> inside_intervals(const std::vector<FillRing>& rings) const;

  int level_;
  std::vector<Scanline> scanlines_;  // ascending latitude
  std::vector<double> scan_lats_;    // the same latitudes, for binary search
  std::vector<std::uint32_t> scan_of_;  // [(hemisphere * rows + row) * 2 + up]: the scanline's index
};

}  // namespace qtmv::sites
