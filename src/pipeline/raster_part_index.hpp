// The index of raster parts: a GDAL VRT mosaic of the bands of rows that raster tile jobs wrote
// (-tile K/N -part PART.tif, then -merge PARTS -of VRT index.vrt).
//
// A raster part is rows [first_row, end_row) of the whole raster (lon/lat: floor((K-1) H / N) to
// floor(K H / N) of its H rows; QTM-coded: the rows of tile K's cells), with the whole raster's
// width, pixel size, SRS, bands, type, nodata and band descriptions, its geotransform starting at
// its first row; its pixels are those rows' of the whole run's raster. Its metadata keeps the
// part's identity (part_index.hpp: QTMV_BANDS, QTMV_RASTER, QTMV_ROWS beside the shared items).
//
// The index is written as GDALBuildVRT would write it (one SimpleSource per part and band, paths
// relative to the index where they can be), but as text: GDALBuildVRT refuses the QTM-coded
// raster (it has no geotransform) and keeps neither the parts' metadata (QTM_LEVEL, QTM_LAYOUT)
// nor the bands' descriptions and unit; the index keeps the whole run's.
#pragma once

#include <string>
#include <vector>

#include "pipeline/part_index.hpp"

namespace qtmv::pipeline {

/// Reads and checks the raster parts of `files` and writes their VRT at `path` (named as
/// `destination`; paths relative to its directory). Throws VoronoiError naming the file at fault:
/// not a raster part (a vector part among them), a part of another run (check_same_run), of
/// another raster (layout, size), bands, data type or nodata than the first, a tile given twice,
/// tiles missing (listed), rows that do not join.
PartIndexSummary write_raster_part_index(const std::vector<std::string>& files, const std::string& path,
                                         const std::string& destination);

}  // namespace qtmv::pipeline
