// The pipeline: sites from an OGR source -> labels for every cell of a QTM level -> a vector or
// raster dataset. The library side of the qtmvoronoi tool, in the style of GDAL's *_lib.cpp
// utilities: an options struct, a progress callback that can stop the run, a message sink;
// failures are exceptions (never exit()), and the destination is written all or nothing.
#pragma once

#include <string>

#include "pipeline/voronoi_error.hpp"
#include "pipeline/voronoi_options.hpp"

namespace qtmv {

/// Runs the whole pipeline from `source` (any OGR dataset name) to `destination` (with
/// options.tile_count, a tile job's product; with options.merge, from tile products). Checks the
/// options, the destination (an existing one is an error unless options.overwrite) and the
/// memory before any work; writes into a temporary directory beside the destination and renames
/// the result into place after a clean close (/vsi* destinations are written directly).
/// Throws VoronoiError, or Interrupted when the progress callback returned false; on any throw
/// the destination is untouched and the temporary files are gone.
VoronoiSummary run_voronoi(const std::string& source, const std::string& destination, const VoronoiOptions& options);

}  // namespace qtmv
