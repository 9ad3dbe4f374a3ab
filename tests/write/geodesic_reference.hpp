// References for the writers' geodesic measures, straight from GeographicLib: shared by the
// write tests.
#pragma once

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/PolygonArea.hpp>

#include "grid/qtm.hpp"

namespace qtmv::write::test {

/// The WGS84 ellipsoid's area (square metres).
inline const double kEllipsoidArea = GeographicLib::Geodesic::WGS84().EllipsoidArea();

/// Area (square metres) of a cell with its vertices joined by geodesics (PolygonArea).
inline double cell_area(grid::Code code, int level) {
  grid::LonLat ring[grid::kMaxPolygonCorners];
  const int n = grid::cell_polygon(grid::cell_of(code, level), level, ring);
  GeographicLib::PolygonArea polygon(GeographicLib::Geodesic::WGS84());
  for (int k = 0; k < n; ++k) polygon.AddPoint(ring[k].lat, ring[k].lon);
  double perimeter = 0, area = 0;
  polygon.Compute(false, false, perimeter, area);
  return area;
}

}  // namespace qtmv::write::test
