// The OGR reader: one layer of any vector dataset GDAL opens (path or /vsi* path) becomes the
// sites of a QTM level: site pieces, site cells and fixed cells for the labeller, and the site
// table for the writers.
//
// Each feature is one site; site ids count the features kept, in reading order (0, 1, 2, ...).
// Geometries: Point, LineString, Polygon, their Multi forms and GeometryCollections of them;
// curves are linearised (getLinearGeometry), Z and M dropped; other types skip the feature.
// Coordinates go to WGS84 lon/lat (traditional GIS order) through OGR/PROJ; they are checked
// (finite, in range) before the transformation, because GDAL 3.6 hangs on EPSG:3857 coordinates
// near +-1e20.
#pragma once

#include <cstdint>
#include <string>

#include "sites/site_options.hpp"
#include "sites/site_table.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

struct ReadSummary {
  std::uint64_t features = 0;           ///< features the layer gave (after -where)
  std::uint64_t sites = 0;              ///< features kept as sites
  std::uint64_t skipped = 0;            ///< features skipped (each reported with its FID)
  std::uint64_t skipped_empty = 0;      ///< empty or missing geometry
  std::uint64_t skipped_type = 0;       ///< unsupported geometry type
  std::uint64_t skipped_coordinate = 0; ///< NaN, infinite or out-of-range coordinate (before or after transformation)
  std::uint64_t skipped_transform = 0;  ///< the coordinate transformation failed
  std::uint64_t skipped_unreadable = 0; ///< the driver could not decode the feature
  std::uint64_t invalid_polygons = 0;   ///< features with an invalid polygon (each reported with its FID)
  std::uint64_t repaired_polygons = 0;  ///< of them, repaired by -makevalid
  std::uint64_t sites_without_own_cell = 0;  ///< sites all of whose cells went to other sites
  std::uint64_t vertex_steps = 0;       ///< traced steps through a grid vertex (informative)
  std::uint64_t wrapped_features = 0;   ///< features with edges joined the short way across +-180 (-wrap auto)
  double rasterise_seconds = 0;         ///< of the read, the time spent tracing, filling and claiming cells (s)
};

/// What the readers hand on.
struct SiteSet {
  SiteGeometry geometry;  ///< pieces, site cells and fixed cells (claims resolved by options.distance)
  SiteTable table;        ///< per site: FID, attributes, cell counts
  ReadSummary summary;
  /// A tile job's sites only (ReadOptions::tile_range): those that can own a cell of its tile,
  /// in the order of the whole source; their layer and FID name them in it.
  bool subset = false;
  std::uint64_t source_features = 0;  ///< with `subset`: the features of the whole source (after -where)
};

/// Reads the sites of `dataset` at options.level. Warnings (a skipped feature, a layer without
/// CRS, sites left without a cell) and the summary line go to options.messages.
/// Throws ReadError: unreadable dataset, missing layer (the message lists the layers), bad
/// -where/-sql/-s_srs (GDAL's message included), a skipped feature under -strict, no usable site;
/// Interrupted when options.progress returns false; std::invalid_argument for a bad level.
SiteSet read_sites(const std::string& dataset, const ReadOptions& options);

}  // namespace qtmv::sites
