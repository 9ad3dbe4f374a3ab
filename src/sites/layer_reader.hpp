// Reading one layer (gdal_rasterize's ProcessLayer is the model): its -where filter, its CRS and
// the transformation to WGS84; its features read by GDAL on the calling thread in chunks, which
// are examined, settled in feature order (reported and made into jobs), built and appended in
// steps beside the reading; then its warnings. Each layer's sites follow the layer before's
// (composite sites), each with its own CRS, checks and messages.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <ogr_spatialref.h>

#include "gdal/error_capture.hpp"
#include "sites/ogr_site_reader.hpp"
#include "sites/ogr_source.hpp"
#include "sites/read_times.hpp"
#include "sites/site_batch.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

/// What the layers add to, one after another, for read_sites to sum up.
struct ReadTotals {
  /// Sums into `out` (its geometry at options.level); `threads` build the sites; `time_jobs`:
  /// each job is timed (the read is traced).
  ReadTotals(SiteSet& out, const ReadOptions& options, int threads, bool time_jobs);

  SiteSet& out;               ///< the sites so far, their table and the summary's counts
  SiteBuilders builders;      ///< one per thread, kept from layer to layer
  ReadTimes times;            ///< of the read's parts, for the read trace
  std::string validity_text;  ///< the layers' invalid polygons, for the summary line
};

/// Reads layer `layer_number` of `source` into `totals`: its sites appended (site ids go on from
/// the layer before's), its source layer added to the site table, its counts to the summary.
/// Coordinates go to `wgs84` (traditional GIS order). Warnings go to options.messages; GDAL's
/// messages are caught by `errors`. Throws ReadError (bad -where or -s_srs, no transformation, a
/// skipped feature under -strict, reading failed, no usable site) and Interrupted.
/// `selected`, if given, holds the features to read instead of the layer's (a tile job's,
/// tile_selection.hpp); they are taken from it.
void read_layer(const OgrSource& source, std::size_t layer_number, const ReadOptions& options,
                gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84, ReadTotals& totals,
                std::vector<OGRFeatureUniquePtr>* selected = nullptr);

}  // namespace qtmv::sites
