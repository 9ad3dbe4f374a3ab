// The output driver of a run: -of, or the destination's extension, as GDAL's utilities guess it.
#pragma once

#include <string>

#include "pipeline/voronoi_options.hpp"

namespace qtmv {

/// The output driver and kind a run would use: options.format (-of), or the first GDAL driver
/// whose extensions (GDAL_DMD_EXTENSIONS) list the destination's and that can create vectors
/// (preferred) or rasters, as `kind` allows. Throws VoronoiError.
struct OutputFormat {
  std::string driver;
  bool raster = false;
};
OutputFormat choose_output_format(const std::string& destination, const std::string& format, OutputKind kind);

}  // namespace qtmv
