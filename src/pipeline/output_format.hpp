// The output driver of a run: -of, or the destination's extension, as GDAL's utilities guess it.
#pragma once

#include <string>

#include "pipeline/voronoi_options.hpp"

namespace qtmv {

/// The output driver and kind a run would use: options.format (-of), the driver whose connection
/// prefix (GDAL_DMD_CONNECTION_PREFIX: PG:, ...) the destination starts with, or the first GDAL driver
/// whose extensions (GDAL_DMD_EXTENSIONS) list the destination's and that can create vectors
/// (preferred) or rasters, as `kind` allows. Throws VoronoiError.
struct OutputFormat {
  std::string driver;
  bool raster = false;
};
OutputFormat choose_output_format(const std::string& destination, const std::string& format, OutputKind kind);

/// Whether the GDAL driver `driver` writes to a connection (it has a connection prefix: PG:,
/// MYSQL:, MSSQL:, ...) rather than to files.
bool is_database_driver(const std::string& driver);

}  // namespace qtmv
