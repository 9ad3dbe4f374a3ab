// One cell edge's geodesic measures in the fixed point that the regions' areas and the Voronoi
// edges' lengths are summed in: integers, so that sums do not depend on the order of adding,
// and the same bits on the CPU and on CUDA devices (geodesic_math.hpp's deterministic solver).
#pragma once

#include <cmath>
#include <cstdint>

#include "grid/qtm_geometry.hpp"
#include "grid/qtm_host_device.hpp"
#include "measure/geodesic_math.hpp"

namespace qtmv::measure {

/// The resolution (square metres) of the sums of edges' areas to the equator (S12).
constexpr double kAreaUnit = 1.0 / 1024;
/// The resolution (metres) of the sums of edges' lengths.
constexpr double kLengthUnit = 1.0 / (1 << 30);

/// A cell edge: the geodesic from -> to (degrees).
struct EdgeEnds {
  grid::LonLat from, to;
};

/// An edge's geodesic area to the equator (S12, in kAreaUnit; negative for a clockwise sweep)
/// and its length (s12, in kLengthUnit).
struct EdgeUnits {
  std::int64_t area = 0, length = 0;
};

/// x rounded to the nearest integer, halves away from zero, by exact operations only (floor), so
/// that host and device round alike.
QTMV_HD inline std::int64_t nearest_integer(double x) {
  return static_cast<std::int64_t>(x >= 0 ? ::floor(x + 0.5) : -::floor(0.5 - x));
}

/// `metres` in kLengthUnit, rounded.
QTMV_HD inline std::int64_t length_units(double metres) { return nearest_integer(metres / kLengthUnit); }

/// An edge's measures from its geodesic.
QTMV_HD inline EdgeUnits edge_units_of(const InverseSolution& g) {
  EdgeUnits units;
  units.area = nearest_integer(g.S12 / kAreaUnit);
  units.length = length_units(g.s12);
  return units;
}

/// The measures of one edge on `ellipsoid`.
QTMV_HD inline EdgeUnits edge_units(const Ellipsoid& ellipsoid, const EdgeEnds& edge) {
  return edge_units_of(geodesic_inverse(ellipsoid, edge.from.lat, edge.from.lon, edge.to.lat, edge.to.lon));
}

}  // namespace qtmv::measure
