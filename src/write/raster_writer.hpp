// The raster writer: the labels of every cell of a level as a GDAL raster, either the
// QTM-coded raster (one pixel per cell, not georeferenced) or an EPSG:4326 lon/lat grid.
//
// Bands (RasterGrid::bands, -bands: any of them, in the order given; by default all three, the
// distance only where the labels have distances), described "site_fid", "boundary", "distance_m":
//   fid       the FID of the cell's site (table.sites[site].fid)
//   boundary  1 on boundary cells, else 0
//   distance  distance from the cell's centre to its site (metres, unit "m")
// Only the labels the bands need are asked for (no distances, no boundary flags otherwise).
//
// One data type and one nodata value for all bands: GDAL's Create takes one type for all bands,
// and GeoTIFF keeps one nodata value per file (TIFFTAG_GDAL_NODATA), so an Int32 FID, a Byte
// flag and a Float32 distance cannot share one GeoTIFF. No value is ever changed silently:
//   - default with the distance band: Float32 when every FID is exact in Float32 (every FID up to
//     2^24 = 16 777 216, and larger ones that happen to be), else Float64. Float32 holds the
//     labeller's distances (float metres) and the 0/1 flags exactly, at half Float64's size.
//   - default without it: Int32 when every FID fits it, else Float64; Byte for the boundary band
//     alone.
//   The FIDs are checked only when the fid band is written.
//   - -ot TYPE (RasterGrid::data_type; Byte, UInt16, Int16, UInt32, Int32, Float32, Float64, as
//     gdal_translate): integer types hold distances rounded to whole metres. A FID outside the
//     type (or not exact in Float32) is a WriteError naming -ot and the FID before anything is
//     written; a distance outside it a WriteError naming -ot, the distance and the cell, found
//     while writing (the output is then removed).
//   - nodata (raster_nodata): -1 for signed integer and float types, the type's largest value for
//     unsigned ones (255, 65535, 4294967295), which no FID may then take. FIDs, 0/1 and distances
//     are all >= 0.
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
// Streaming: the writer holds two strips of rows (RasterOptions::strip_bytes, 64 MiB by default,
// for both strips' pixels and one strip's cells' labels): a helper thread fills the next strip
// (raster_strips.hpp: its cells, their labels from the CellLabelSource, the values, on all cores)
// while this thread hands the last one to GDAL, which compresses its blocks on the run's threads.
// The labels are asked for one strip at a time: the QTM-coded raster's strip of pixel rows is one
// range of codes (row octant * 2^L + i holds codes [o * 4^L + i^2, o * 4^L + (i + 1)^2)); a lon/lat
// strip's pixel centres lie on parallels, each one row of cells per octant, so the strip's rows of
// cells are labelled whole (up to one range of codes an octant), or, for pixels much coarser than
// cells, the sorted, de-duplicated codes of its pixels' centres. After each strip that ends a row
// of the driver's blocks those blocks are flushed from GDAL's cache, so the cache holds at most
// one row of blocks. The file does not depend on the number of threads.
//
// Drivers: any GDAL raster driver that can Create (written strip by strip) or only CreateCopy,
// such as COG (written to a staging dataset first: MEM when the whole raster fits one strip's
// budget, else a tiled DEFLATE GeoTIFF beside the destination, removed afterwards). GTiff gets
// TILED=YES, COMPRESS=DEFLATE (with ZLEVEL=1), BIGTIFF=IF_SAFER and INTERLEAVE=BAND unless
// creation_options name them (5.6x faster than GDAL's DEFLATE defaults at level 11, and no
// larger); GTiff and COG get NUM_THREADS = the run's threads (thread_count(0)) unless named. A driver that cannot create the band type (PNG: Byte/UInt16 only)
// is a WriteError, never a silent truncation.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sites/site_table.hpp"
#include "write/cell_labels.hpp"

namespace qtmv::write {

/// Buffers of one strip (bytes) when RasterOptions::strip_bytes is 0.
constexpr std::uint64_t kDefaultStripBytes = std::uint64_t{64} << 20;

/// The bands' data type for these options (RasterGrid::data_type or the default above) and labels
/// with or without distances, as GDAL names it ("Float32"). Throws WriteError naming -ot for an
/// unknown type, naming -ot (or the default) and the FID when the fid band is written and a FID
/// does not fit the type exactly, and naming -bands for bands the labels cannot give.
std::string raster_data_type(const RasterOptions& options, bool with_distance, const sites::SiteTable& table);

/// The default type of `bands` before the FIDs are known: Float32 with the distance band, else
/// Int32 with the fid band, else Byte.
std::string default_raster_data_type(const std::vector<RasterBand>& bands);

/// Throws WriteError when `data_type` (-ot) is not one of the types above (empty is fine).
void check_raster_data_type(const std::string& data_type);

/// Nodata value of every band for the data type `data_type` (a GDAL name): -1, or the largest
/// value of an unsigned integer type.
double raster_nodata(const std::string& data_type);

/// What write_raster wrote.
struct RasterWritten {
  /// Per site id: 1 when some pixel holds the site (the QTM-coded raster: some cell), else 0.
  std::vector<std::uint8_t> site_seen;
};

/// Writes the raster to `path` with options.driver, strip by strip, asking `labels` for each
/// strip's labels. Throws WriteError naming the destination, the band and GDAL's message on any
/// failure (after removing what it had written), and Interrupted when options.progress returns
/// false. A site id outside the table is an error.
RasterWritten write_raster(const std::string& path, const CellLabelSource& labels, const sites::SiteTable& table,
                           const RasterOptions& options);

/// The same from every cell's labels in arrays.
RasterWritten write_raster(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const RasterOptions& options);

/// Host bytes the writer's buffers take at most for these options and labels with or without
/// distances: the strips, or one row of 256-row blocks in GDAL's cache (bands x 8 bytes a pixel
/// at most, and at most GDAL_CACHEMAX) where that is larger.
std::uint64_t raster_buffer_bytes(int level, const RasterOptions& options, bool with_distance);

/// The raster's size (pixels) for these options and level, as write_raster would make it.
/// Throws WriteError for bad -tr / -ts values or a size beyond GDAL's int.
struct RasterSize {
  int width = 0, height = 0;
  double x_resolution = 0, y_resolution = 0;  ///< lonlat only (degrees)
};
RasterSize raster_size(int level, const RasterOptions& options);

}  // namespace qtmv::write
