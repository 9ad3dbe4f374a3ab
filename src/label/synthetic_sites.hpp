// Synthetic sites for the labeller's tests and the benchmark (as S2's *_testing.h): points,
// great-circle arcs and fixed cells put straight into a SiteGeometry, without the readers. Arcs
// are cut by the readers' piece rule (label_input.hpp, max_piece_degrees).
#pragma once

#include <cstdint>

#include "grid/qtm.hpp"
#include "label/label_input.hpp"

namespace qtmv::label {

/// Adds a point site piece at (lon, lat) (degrees) and its site cell; site_count grows to cover
/// `site`. Throws std::invalid_argument for a negative site or an invalid coordinate.
void add_point(SiteGeometry& g, double lon, double lat, std::int32_t site);

/// Adds the great-circle arc from (lon1, lat1) to (lon2, lat2) (degrees; shorter than 180
/// degrees) cut into pieces no longer than max_piece_degrees(g.level), and the cells the pieces'
/// ends and middles fall in.
void add_arc(SiteGeometry& g, double lon1, double lat1, double lon2, double lat2, std::int32_t site);

/// Adds a fixed cell (a cell inside a polygon of `site`).
void add_fixed_cell(SiteGeometry& g, grid::Code code, std::int32_t site);

}  // namespace qtmv::label
