// The labeller's input port: what the readers hand it, as plain arrays (no GDAL types). The
// readers (src/sites) include this header only, not the labeller.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "common/radix_sort.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_key_ranges.hpp"
#include "label/label_options.hpp"

namespace qtmv::label {

using grid::Vec3;

/// Pieces per shortest cell edge: lines and rings are cut into great-circle arcs no longer than
/// a quarter of the level's shortest cell edge (the readers' path tracer and synthetic sites
/// alike), so that an arc bends from the line it stands for by far less than a cell.
constexpr int kPiecesPerCellEdge = 4;

/// Longest piece at a level (degrees of great-circle arc): 90 / 2^L degrees, the shortest cell
/// edge (along a meridian or the equator), over kPiecesPerCellEdge.
inline double max_piece_degrees(int level) { return 90.0 / kPiecesPerCellEdge / static_cast<double>(1ull << level); }

/// One piece of a site's geometry: a point (a == b) or a great-circle arc from a to b, both unit
/// vectors. Arcs should be short (max_piece_degrees): any length below a quarter circle is
/// correct, but long arcs prune badly.
struct SitePiece {
  Vec3 a, b;
  std::int32_t site;
};

/// A cell that a site passes through, with the pieces of that site in it (for the cell rule,
/// only the code and the site are used).
struct SiteCell {
  grid::Code code;
  std::int32_t site;
  std::uint32_t piece_begin, piece_end;  ///< range in the piece array
};

/// A cell inside a polygon site: it keeps that site at distance 0 (the lower id when two
/// polygons claim it). Without fixed nodes its centre is also a candidate point of the site for
/// the other cells, but one inside the polygon's rings is never nearer to another cell than the
/// rings are.
struct FixedCell {
  grid::Code code;
  std::int32_t site;
};

/// A quadtree node wholly inside a polygon site (a "cover" entry): every cell below it at the
/// labelling level is a fixed cell of that site. Readers give a polygon's interior as such nodes
/// plus the fixed cells along its rings, so that the work follows the rings, not the area. With
/// fixed nodes, claimed cells are no candidates for other cells: the polygons' rings must be
/// given too (as pieces, or site cells for the cell rule), as the readers give them.
struct FixedNode {
  grid::Code code;      ///< the node's code at its own level
  std::int32_t level;   ///< the node's level (0 .. the labelling level)
  std::int32_t site;
};

/// The input of one labelling run: views of the arrays below (or of the caller's own).
struct LabelInput {
  int level = 0;                      ///< QTM level to label (0..24)
  std::int32_t site_count = 0;        ///< site ids run from 0 to site_count - 1
  const SitePiece* pieces = nullptr;  ///< for the exact rule
  std::size_t piece_count = 0;
  const SiteCell* site_cells = nullptr;  ///< for the cell rule
  std::size_t site_cell_count = 0;
  const FixedCell* fixed_cells = nullptr;  ///< both rules
  std::size_t fixed_cell_count = 0;
  const FixedNode* fixed_nodes = nullptr;  ///< both rules: their cells are fixed cells
  std::size_t fixed_node_count = 0;
};

/// An array of SiteGeometry: resize() leaves new elements uninitialised (DefaultInitAllocator), so
/// that the readers' threads that fill a batch of sites touch its pages first.
template <class T>
using SiteArray = std::vector<T, DefaultInitAllocator<T>>;

/// Pieces, site cells, fixed cells and fixed nodes gathered for one level (what the readers produce).
struct SiteGeometry {
  int level = 0;
  std::int32_t site_count = 0;
  SiteArray<SitePiece> pieces;
  SiteArray<SiteCell> site_cells;
  SiteArray<FixedCell> fixed_cells;
  SiteArray<FixedNode> fixed_nodes;
  LabelInput input() const {
    LabelInput in;
    in.level = level;
    in.site_count = site_count;
    in.pieces = pieces.data();
    in.piece_count = pieces.size();
    in.site_cells = site_cells.data();
    in.site_cell_count = site_cells.size();
    in.fixed_cells = fixed_cells.data();
    in.fixed_cell_count = fixed_cells.size();
    in.fixed_nodes = fixed_nodes.data();
    in.fixed_node_count = fixed_nodes.size();
    return in;
  }
};

/// The cells that the input's fixed cells and fixed nodes claim, each held by the lowest site that
/// claims it: grid::lowest_owner_partition of their quadtree-key ranges (the labeller's cover and
/// the readers' counts).
inline std::vector<grid::KeyRange> held_claims(const LabelInput& input) {
  const auto cells = static_cast<std::int64_t>(input.fixed_cell_count);
  const auto nodes = static_cast<std::int64_t>(input.fixed_node_count);
  // Not zeroed: every range is written below, on all cores.
  std::vector<grid::KeyRange, DefaultInitAllocator<grid::KeyRange>> ranges(static_cast<std::size_t>(cells + nodes));
  // On all cores where the includer is built with OpenMP (the readers and the labeller are).
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(thread_count(0))
#endif
  for (std::int64_t k = 0; k < cells; ++k) {
    const FixedCell& f = input.fixed_cells[k];
    const std::uint64_t key = grid::quadtree_key(grid::cell_of(f.code, input.level), input.level);
    ranges[k] = {key, key, f.site};
  }
#ifdef _OPENMP
#pragma omp parallel for schedule(static) num_threads(thread_count(0))
#endif
  for (std::int64_t k = 0; k < nodes; ++k) {
    const FixedNode& n = input.fixed_nodes[k];
    ranges[cells + k] = grid::node_key_range(grid::cell_of(n.code, n.level), n.level, input.level, n.site);
  }
  // key_range_before's order: by first key, then owner.
  sort_by_pair(ranges, [](const grid::KeyRange& r) { return r.first; },
               [](const grid::KeyRange& r) { return static_cast<std::uint32_t>(r.owner); });
  return grid::lowest_owner_partition_of_sorted(ranges);
}

}  // namespace qtmv::label
