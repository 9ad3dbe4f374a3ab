// Geodesic measures of the vector outputs on the WGS84 ellipsoid (GeographicLib): the regions'
// areas (area_m2) and the Voronoi edges' lengths (length_m).
//
// A region's area is that of the region whose cell vertices are joined by geodesics: the cells
// then tile the ellipsoid exactly, so the areas add up to its area. Each ring is taken with the
// region on its left, so a region around a pole gets its own area, not the rest of the Earth.
#pragma once

#include <cstddef>
#include <vector>

#include "write/region_tracer.hpp"

namespace qtmv::write {

/// Areas (square metres) of regions [first, last) of `regions`, traced at `level`, on all cores:
/// rings are measured one a thread, long rings in chunks of consecutive edges whose areas add up
/// (each chunk closed by a geodesic, the chunks' ends making a ring of their own).
std::vector<double> region_areas(const std::vector<Region>& regions, std::size_t first, std::size_t last, int level);

/// Geodesic length (metres) of the segment between two points (degrees).
double geodesic_length(const LonLat& a, const LonLat& b);

}  // namespace qtmv::write
