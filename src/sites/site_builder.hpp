// Builds the labeller's site geometry from WGS84 lon/lat coordinates, one site at a time: points,
// lines and polygons are unwrapped across +-180, traced onto cells and cut into pieces; polygons
// are filled (as covers: fixed nodes and fixed cells). Knows nothing of OGR, so the tests can drive it directly.
#pragma once

#include <cstdint>
#include <vector>

#include "grid/qtm.hpp"
#include "sites/path_tracer.hpp"
#include "sites/polygon_fill.hpp"
#include "sites/site_options.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

/// A ring or path: vertices (degrees, lon then lat, latitudes in [-90, 90]).
using LonLatPath = std::vector<grid::LonLat>;

class SiteBuilder {
 public:
  SiteBuilder(int level, EdgeShape edges, WrapMode wrap);

  /// Starts the next site and returns its id (0, 1, 2, ...).
  std::int32_t begin_site();
  /// A point of the current site.
  void add_point(const grid::LonLat& point);
  /// A line of the current site (open path; one vertex makes a point).
  void add_line(const grid::LonLat* vertices, std::size_t count);
  /// A polygon of the current site: rings[0] the outer ring, the others holes; each ring closed
  /// (last vertex repeats the first; a missing closing vertex is added).
  void add_polygon(const std::vector<LonLatPath>& rings);
  /// Finishes the current site: its hits become site cells.
  void end_site();

  /// The geometry so far (site cells of finished sites only); claims are not resolved yet.
  SiteGeometry& geometry() { return geometry_; }
  /// Hands the geometry over (the builder is empty afterwards).
  SiteGeometry take_geometry();
  /// Edges of the current (or last) site that -wrap auto joined the short way across +-180.
  std::size_t short_way_edges() const { return short_way_edges_; }
  /// Cell pairs sharing only a vertex accepted while tracing (lines through a grid vertex).
  std::uint64_t vertex_steps() const { return tracer_.vertex_steps(); }

 private:
  int level_;
  EdgeShape edges_;
  WrapMode wrap_;
  PathTracer tracer_;
  PolygonFiller filler_;
  SiteGeometry geometry_;
  std::int32_t current_ = -1;
  std::vector<CellHit> hits_;
  std::vector<grid::Code> fill_cells_;
  std::vector<PolygonFiller::CoverNode> fill_nodes_;
  std::size_t short_way_edges_ = 0;
};

}  // namespace qtmv::sites
