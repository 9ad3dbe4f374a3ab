// A feature's geometry as coordinate runs (points, lines, polygons' rings) in the source CRS,
// before any transformation: what the reader checks, transforms and hands to the site builders.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <ogr_geometry.h>

namespace qtmv::sites {

/// A feature's geometry as coordinate runs in the source CRS, before any transformation.
struct FeatureParts {
  enum Kind { kPoint, kLine, kRing };
  struct Part {
    Kind kind;
    std::size_t begin, end;  // range in x, y
    int polygon;             // rings: index of their polygon
  };
  std::vector<double> x, y;
  std::vector<Part> parts;
  int polygons = 0;

  void add_curve(const OGRSimpleCurve& curve, Kind kind, int polygon);
};

/// Gathers the parts of a (linear) geometry; false with `reason` for an unsupported type.
bool gather_parts(const OGRGeometry& geometry, FeatureParts& out, std::string& reason);

/// The points of a geometry's curves (a bound on its vertices, for the chunks' size).
std::size_t point_count(const OGRGeometry& geometry);

}  // namespace qtmv::sites
