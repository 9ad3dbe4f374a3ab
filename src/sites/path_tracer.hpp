// Tracing lines and rings onto QTM cells: every cell the line passes through, with no gaps, and
// the line cut into short great-circle arcs ("pieces") for the labeller.
//
// Each edge (lon/lat straight segment or WGS84 geodesic) is sampled at equal steps of its
// parameter, at most a quarter of the level's shortest cell edge apart (22.5 / 2^L degrees of
// arc); consecutive samples make one piece. Between the two ends of a piece the edge is bisected
// until consecutive samples lie in the same cell or in cells sharing an edge, so the cells found
// form a chain without gaps; a pair that only shares a vertex is accepted once the step is below
// 1e-9 degrees (the edge passes through that vertex), with the cell that owns the vertex point
// (by the spec's point location) put between them.
#pragma once

#include <cstdint>
#include <vector>

#include "grid/qtm.hpp"
#include "sites/site_options.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

/// A cell that a piece passes through.
struct CellHit {
  grid::Code code;
  std::uint32_t piece;  ///< index in the piece array
};

/// Longest piece at a level (degrees of great-circle arc): the labeller's input rule.
using label::max_piece_degrees;

class PathTracer {
 public:
  PathTracer(int level, EdgeShape shape);

  /// Traces the path through `vertices` (degrees, longitudes unwrapped as by unwrap_longitudes)
  /// for `site`: appends its pieces to `pieces` and, in path order, the cells each piece passes
  /// through to `hits` (a cell repeats when consecutive pieces share it). A path of one vertex
  /// (or whose vertices all coincide) is one point piece. When `samples` is given, the sample
  /// points along the path (degrees, unwrapped, ends included) are appended to it: the densified
  /// path that polygon fill uses for geodesic edges. `straight` (may be null): one flag per edge
  /// (UnwrappedPath::straight); a flagged edge is straight in lon/lat whatever the shape.
  void trace(const grid::LonLat* vertices, std::size_t count, std::int32_t site, label::SiteArray<SitePiece>& pieces,
             std::vector<CellHit>& hits, std::vector<grid::LonLat>* samples = nullptr,
             const std::uint8_t* straight = nullptr);

  /// Pairs of consecutive cells that share only a vertex (accepted at the bisection limit); for tests.
  std::uint64_t vertex_steps() const { return vertex_steps_; }

 private:
  struct Edge;
  void refine(const Edge& edge, double t0, grid::Code c0, double t1, grid::Code c1, std::uint32_t piece,
              std::vector<CellHit>& hits, int depth);

  int level_;
  EdgeShape shape_;
  double max_piece_;
  std::uint64_t vertex_steps_ = 0;
};

/// Whether two cells of a level share an edge.
bool share_edge(grid::Code a, grid::Code b, int level);
/// Whether two cells of a level share at least a vertex; `vertex` (optional) receives one shared
/// vertex (degrees).
bool share_vertex(grid::Code a, grid::Code b, int level, grid::LonLat* vertex = nullptr);

}  // namespace qtmv::sites
