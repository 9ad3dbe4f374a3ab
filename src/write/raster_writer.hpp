// The raster writer: the labels of every cell of a level as a GDAL raster, either the
// QTM-coded raster (one pixel per cell, not georeferenced) or an EPSG:4326 lon/lat grid.
//
// Bands (described "site_fid", "boundary", "distance_m"):
//   1  the FID of the cell's site (table.sites[site].fid)
//   2  1 on boundary cells, else 0
//   3  distance from the cell's centre to its site (metres); only when labels.distance_m is set
//
// One data type and one nodata value for all bands. GDAL's Create takes one type for all bands,
// and GeoTIFF keeps one nodata value per file (TIFFTAG_GDAL_NODATA), so the spec's per-band
// Int32 / Byte / Float32 with nodata -1 / 255 / NaN cannot be stored in one GeoTIFF. Instead:
//   - with distances:    Float64 (holds every Int32 FID, 0/1 and every Float32 distance exactly)
//   - without distances: Int32 (two bands)
//   - nodata is -1 in every band (FIDs, 0/1 and distances are all >= 0).
//
// When labels.boundary is null, band 2 is computed from labels.site with grid::neighbours (a cell
// is on a boundary when one of its three edge neighbours has another site).
//
// Layouts (RasterOptions::Layout):
//   qtm     width 2^(L+1) - 1, height 8 * 2^L; cell (octant o, row i, col j) is pixel column j,
//           pixel row o * 2^L + i; pixels with j > 2i are nodata. No geotransform, no SRS.
//           Dataset metadata: QTM_LEVEL, QTM_LAYOUT=octant_row_col, QTM_GEOREFERENCED=NO.
//   lonlat  EPSG:4326 (lon, lat order), origin (-180, 90), north up. Each pixel gets the values of
//           the cell holding the pixel's centre (grid::lonlat_to_code).
//           Size: -ts WIDTH HEIGHT gives pixels of 360/WIDTH x 180/HEIGHT degrees over the globe;
//           -tr XRES YRES (degrees) is honoured exactly, with round(360/XRES) x round(180/YRES)
//           pixels (as gdalwarp, the extent then differs from the globe by under half a pixel;
//           centres past 180 wrap, past -90 are nodata). One of a pair left 0: square pixels
//           (height = width / 2). Default: square pixels of 90/2^L degrees, the cell edge along
//           the equator: 4 * 2^L x 2 * 2^L pixels, as many pixels as cells.
//           Dataset metadata: QTM_LEVEL, QTM_LAYOUT=lonlat.
//
// Drivers: any GDAL raster driver that can Create (written strip by strip) or only CreateCopy
// (written to a staging dataset first: MEM up to 1 GiB, else a tiled DEFLATE GeoTIFF beside the
// destination, removed afterwards). GTiff gets TILED=YES, COMPRESS=DEFLATE (with ZLEVEL=1),
// BIGTIFF=IF_SAFER, INTERLEAVE=BAND and NUM_THREADS=ALL_CPUS unless creation_options name them
// (5.6x faster than GDAL's DEFLATE defaults at level 11, and no larger). A driver that cannot create the band type (PNG: Byte/UInt16 only)
// is a WriteError, never a silent truncation.
#pragma once

#include <string>

#include "sites/site_table.hpp"
#include "write/cell_labels.hpp"

namespace qtmv::write {

/// Nodata value of every band of the rasters written.
constexpr double kRasterNodata = -1.0;

/// Writes the raster to `path` with options.driver. Throws WriteError naming the destination,
/// the band and GDAL's message on any failure (after removing what it had written), and
/// Interrupted when options.progress returns false. FIDs must lie in
/// [0, 2^31 - 1]; a site id outside the table is an error.
void write_raster(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const RasterOptions& options);

/// The raster's size (pixels) for these options and level, as write_raster would make it.
/// Throws WriteError for bad -tr / -ts values or a size beyond GDAL's int.
struct RasterSize {
  int width = 0, height = 0;
  double x_resolution = 0, y_resolution = 0;  ///< lonlat only (degrees)
};
RasterSize raster_size(int level, const RasterOptions& options);

}  // namespace qtmv::write
