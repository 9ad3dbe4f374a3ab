// The labels of points along parallels (a lon/lat raster's rows of pixel centres) from the host's
// tree, without each point's cell code being listed, sorted and looked up: along a parallel the
// points of one quadrant fall in the cells of one row of each octant, in column order, and a
// leaf of the tree holds one run of those columns. So a uniform leaf's points are found by a
// search for the end of its run and filled at once; a list leaf's points test its few
// candidates, once per cell. The labels are tree_label_cell's for each point's cell, bit for bit.
#pragma once

#include <cstddef>
#include <cstdint>

#include "label/label_tree.hpp"

namespace qtmv::label {

/// The labels of the cells of tv.level that hold the points (lon[k], lat[r]), r < rows, k < count
/// (degrees: lat in [-90, 90], lon in [-180, 180); each row's longitudes best ascending, where a
/// run of a quadrant is searched rather than walked) into site, metres and boundary (entry
/// r * count + k; metres and boundary may be null: not asked for; metres needs a tree built with
/// distances), the rows on `threads` threads. The cell of a point is grid::lonlat_to_code's.
void tree_label_parallels(const TreeView& tv, const double* lat, int rows, const double* lon, std::size_t count,
                          std::int32_t* site, float* metres, std::uint8_t* boundary, int threads);

}  // namespace qtmv::label
