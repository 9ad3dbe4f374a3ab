// A feature's geometry as coordinate runs (points, lines, polygons' rings) in the source CRS,
// before any transformation: what the reader checks, transforms and hands to the site builders.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <ogr_geometry.h>

#include "common/default_init_allocator.hpp"
#include "grid/qtm_geometry.hpp"

namespace qtmv::sites {

/// Features' geometries as coordinate runs: one feature's, or those of a block of features read
/// together (each feature's parts a range of `parts`), so that a block's features share two
/// arrays that keep their memory from chunk to chunk.
struct FeatureParts {
  enum Kind { kPoint, kLine, kRing };
  struct Part {
    Kind kind;
    std::size_t begin, end;  // range in points
    int polygon;             // rings: index of their polygon in their feature
  };
  /// x (in lon) and y (in lat) in the source CRS; lon/lat degrees once to_lonlat has run.
  DefaultInitVector<grid::LonLat> points;
  std::vector<Part> parts;
  int polygons = 0;  ///< the polygons of the feature being gathered (set to 0 before each feature)

  void add_curve(const OGRSimpleCurve& curve, Kind kind, int polygon);
  /// Drops the parts from part `part_begin` and the points from `point_begin` on (a feature skipped).
  void truncate(std::size_t part_begin, std::size_t point_begin);
  void clear();
};

/// Gathers the parts of a (linear) geometry, appended to `out`; false with `reason` for an
/// unsupported type.
bool gather_parts(const OGRGeometry& geometry, FeatureParts& out, std::string& reason);

/// The points of a geometry's curves (a bound on its vertices, for the chunks' size).
std::size_t point_count(const OGRGeometry& geometry);

}  // namespace qtmv::sites
