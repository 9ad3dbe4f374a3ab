// A raster's bands (-bands): their names on the command line, their descriptions in the file,
// and the list a run writes.
#pragma once

#include <string>
#include <vector>

#include "write/cell_labels.hpp"

namespace qtmv::write {

/// The band's name in -bands: "fid", "boundary", "distance".
const char* raster_band_name(RasterBand band);

/// The band's description in the raster: "site_fid", "boundary", "distance_m".
const char* raster_band_description(RasterBand band);

/// The bands of a -bands list ("fid,distance": names from fid, boundary, distance, separated by
/// commas, in the order the bands are to be written). Throws WriteError naming -bands and the
/// list for an empty list or name, an unknown name, or a band named twice.
std::vector<RasterBand> parse_raster_bands(const std::string& list);

/// The bands written for `grid` by labels with (`with_distance`) or without distances: grid.bands,
/// or when empty fid, boundary (and distance with distances). Throws WriteError naming -bands for
/// a band listed twice, or distance from labels without distances.
std::vector<RasterBand> raster_bands(const RasterGrid& grid, bool with_distance);

/// Whether `bands` holds `band`.
bool has_band(const std::vector<RasterBand>& bands, RasterBand band);

}  // namespace qtmv::write
