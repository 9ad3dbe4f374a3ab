// The output's size, estimated before any work, against the free space where it is written:
// a run that cannot fit its destination's file system is refused at once, not after
// hours of labelling. GDAL's GeoTIFF driver checks the same for uncompressed files, and its
// configuration option CHECK_DISK_FREE_SPACE=NO turns both checks off.
//
// Estimates (bytes as written without compression):
//   raster  width x height pixels x bands x bytes of the band type, as write_raster writes them
//           (the -bands, by default 3; -ot, or by default Float32 with the distance band, else
//           Int32 with the fid band, else Byte; FIDs beyond Float32 make the default Float64,
//           which the estimate cannot know before reading);
//           a driver that can only CreateCopy stages a copy too, which is not counted.
//   vector  the cells layer: one row per cell, kBytesPerCellRow bytes each (measured at level 7:
//           GeoPackage 146, Shapefile 198, FlatGeobuf 195, GeoJSON 302 bytes a row). regions and
//           voronoi_edges grow with the sites, boundary_cells with the boundaries: both unknown
//           before labelling and small beside the cells, so not counted.
#pragma once

#include <cstdint>
#include <string>

#include "write/cell_labels.hpp"

namespace qtmv::write {

struct OutputSize {
  std::uint64_t bytes = 0;  ///< estimated size (bytes, uncompressed)
  std::string what;         ///< how it was counted: "1000000 x 1000000 pixels, 3 bands of Float64"
  std::string smaller;      ///< how to make it smaller: "fewer pixels (-tr, -ts)"
};

/// The raster's size for these options (checked as raster_size does; throws WriteError); a
/// part's (RasterOptions::part_rows) is its rows'.
OutputSize estimate_raster_size(int level, const RasterOptions& options, bool with_distance);

/// The vector output's size: bytes of its cells layer (0 without one).
OutputSize estimate_vector_size(int level, const VectorOptions& options);

/// Bytes the vector output's layers other than cells take per outline cell
/// (label/outline_cells.hpp), at least: about a ring vertex of 16 bytes each (a GeoPackage of the
/// regions of 135 233 points at level 13 holds 23).
constexpr std::uint64_t kBytesPerOutlineCell = 16;

/// The vector output's size once labelled (bytes): estimate_vector_size's cells layer, and
/// kBytesPerOutlineCell for each of `outline_cells` where any other layer is written.
std::uint64_t expected_vector_bytes(int level, const VectorOptions& options, std::uint64_t outline_cells);

/// A GeoPackage or SQLite output of at least this many bytes gets pages of kLargeSqlitePageSize.
constexpr std::uint64_t kLargeSqliteFileBytes = std::uint64_t{64} << 20;
/// SQLite's largest page (bytes): a region of thousands of vertices fits one page instead of a
/// chain of 4096-byte overflow pages. Measured on the regions of 135 233 points at level 13: the
/// rows written 2x faster, the file 18% smaller. Small files keep SQLite's 4096 (a table or index
/// takes a page at least).
constexpr std::uint32_t kLargeSqlitePageSize = 65536;

/// The page size (bytes) for a new SQLite file (GeoPackage, SQLite) of about `bytes`:
/// kLargeSqlitePageSize from kLargeSqliteFileBytes up, else 0 (SQLite's default).
inline std::uint32_t sqlite_page_size(std::uint64_t bytes) { return bytes >= kLargeSqliteFileBytes ? kLargeSqlitePageSize : 0; }

/// Bytes per row of the cells layer for `driver` (a polygon of 4 points and 4 fields).
std::uint64_t bytes_per_cell_row(const std::string& driver);

/// "24.0 TB", "80.1 GB", "512 bytes": decimal units, as df -H and GDAL's messages.
std::string format_bytes(double bytes);

/// Refuses (WriteError) an output of `size` that does not fit the free space of the directory
/// `destination` is written to: "'DST': the raster takes about 24.0 TB uncompressed (...) and
/// 'DIR' has 80.1 GB free; ...". Does nothing for /vsi* destinations, a missing directory (the
/// caller reports it), a file system that does not say its free space, or with the GDAL
/// configuration option CHECK_DISK_FREE_SPACE=NO. `kind` names the output ("raster", "cells
/// layer"). For tests, the configuration option QTMV_FAULT_DISK_FREE_BYTES=N pretends N bytes free.
void check_disk_space(const std::string& destination, const OutputSize& size, const std::string& kind);

}  // namespace qtmv::write
