// The Voronoi edges' topology: every cell edge between two sites, gathered from the outline
// cells and sorted by pair of sites, and one pair's edges linked into lines and measured (the
// voronoi_edges layer, vector_writer.hpp).
#pragma once

#include <cstdint>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"
#include "write/region_tracer.hpp"

namespace qtmv::write {

/// One cell edge between two sites: key = site a << 32 | site b (a < b), edge = the cell of
/// site a << 2 | the edge's index in its drawn ring.
struct EdgeRef {
  std::uint64_t key, edge;
  bool operator<(const EdgeRef& o) const { return key < o.key || (key == o.key && edge < o.edge); }
};

/// Every edge between cells of different sites, once (from the cell of the lower site id: the
/// two drawings of an edge on +-180, at +180 and -180, are one edge), sorted by pair. Such an
/// edge has a boundary cell on each side: the outline cells hold them all.
DefaultInitVector<EdgeRef> gather_edges(const label::Outlines& outlines);

/// The lines of one pair and their geodesic length.
struct PairLines {
  std::vector<std::vector<LonLat>> lines;  ///< (degrees)
  double length_m = 0;                      ///< (metres)
};

/// Links a pair's cell edges (all with site a on their left) into lines: an edge continues the
/// one that ends where it starts. Edges that do not meet (across +-180, across a pole) start
/// new lines. The length is the sum of the edges' geodesic lengths in kLengthUnit; `measured`
/// (may be null) is that sum over the edges off the cut at +-180, from the regions' pass
/// (RegionAreaSums), and only the others are solved here: the same sum either way.
/// `level` is the cells' QTM level.
PairLines link_pair(const EdgeRef* begin, const EdgeRef* end, int level, const std::uint64_t* measured);

}  // namespace qtmv::write
