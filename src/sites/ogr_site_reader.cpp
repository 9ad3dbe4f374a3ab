#include "sites/ogr_site_reader.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <chrono>
#include <cstddef>
#include <string>

#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm_checks.hpp"
#include "sites/fid_list.hpp"
#include "sites/layer_reader.hpp"
#include "sites/ogr_source.hpp"
#include "sites/read_times.hpp"
#include "sites/site_cells.hpp"
#include "sites/tile_selection.hpp"

namespace qtmv::sites {

EdgeShape parse_edge_shape(const std::string& text) {
  if (text == "lonlat") return EdgeShape::lonlat;
  if (text == "geodesic") return EdgeShape::geodesic;
  throw ReadError("-edges: '" + text + "' is not one of lonlat, geodesic");
}

WrapMode parse_wrap_mode(const std::string& text) {
  if (text == "auto") return WrapMode::automatic;
  if (text == "none") return WrapMode::none;
  throw ReadError("-wrap: '" + text + "' is not one of auto, none");
}

DistanceRule parse_distance_rule(const std::string& text) {
  if (text == "exact") return DistanceRule::exact;
  if (text == "cell") return DistanceRule::cell;
  throw ReadError("-distance: '" + text + "' is not one of exact, cell");
}

namespace {

/// Sums up the read (after its last layer): the claims resolved by options.distance, each
/// site's cell counts, the sites left without a cell of their own, the read trace, and the
/// summary line.
void sum_up(ReadTotals& totals, const std::string& where_all, const ReadOptions& options,
            std::chrono::steady_clock::time_point read_start) {
  SiteSet& out = totals.out;
  ReadSummary& summary = out.summary;
  ReadTimes& times = totals.times;
  summary.vertex_steps += totals.builders.vertex_steps();
  const auto claims_start = std::chrono::steady_clock::now();
  const SiteCellCounts counts = resolve_claims(out.geometry, options.distance);
  times.rasterise += std::chrono::steady_clock::now() - claims_start;
  if (times.time_jobs) {
    trace_printf(TraceStage::read,
                 "%d threads: features read %.3f s and settled %.3f s on the reading thread; beside it "
                 "(thread time) examined %.3f s, sites built %.3f s (longest job %.3f s), appended %.3f s; "
                 "not hidden by the reading %.3f s; claims %.3f s; whole read %.3f s",
                 totals.builders.threads(), times.read_s, times.settled_s, times.examined_s, times.built_s,
                 times.longest_job_s, times.appended_s,
                 std::chrono::duration<double>(times.rasterise).count() - seconds_since(claims_start),
                 seconds_since(claims_start), seconds_since(read_start));
  }
  summary.rasterise_seconds = std::chrono::duration<double>(times.rasterise).count();
  FidList without_cell;
  for (std::size_t s = 0; s < out.table.sites.size(); ++s) {
    SiteRecord& r = out.table.sites[s];
    r.site_cells = counts.site_cells[s];
    r.fixed_cells = counts.fixed_cells[s];
    r.has_own_cell = counts.has_own_cell[s];
    if (!r.has_own_cell) without_cell.add(r.fid);
  }
  summary.sites_without_own_cell = without_cell.count();
  if (without_cell.count() > 0 && options.warn_sites_without_cell) {
    tell(options.messages, Severity::warning,
         where_all + ": " + std::to_string(without_cell.count()) + " site(s) have no cell of their own at level " +
             std::to_string(options.level) + " (FIDs " + without_cell.text() + "); they are still written");
  }
  std::string line = where_all + ": " + std::to_string(summary.features) + " features, " +
                     std::to_string(summary.sites) + " sites, " + std::to_string(out.geometry.pieces.size()) +
                     " pieces, " + std::to_string(out.geometry.site_cells.size()) + " site cells, " +
                     std::to_string(out.geometry.fixed_cells.size()) + " fixed cells and " +
                     std::to_string(out.geometry.fixed_nodes.size()) + " fixed nodes at level " +
                     std::to_string(options.level);
  line += totals.validity_text;
  if (summary.skipped > 0) {
    line += "; " + std::to_string(summary.skipped) + " features skipped (" + std::to_string(summary.skipped_empty) +
            " empty, " + std::to_string(summary.skipped_type) + " unsupported type, " +
            std::to_string(summary.skipped_coordinate) + " bad coordinate, " +
            std::to_string(summary.skipped_transform) + " failed transformation, " +
            std::to_string(summary.skipped_unreadable) + " unreadable)";
  }
  tell(options.messages, summary.skipped > 0 ? Severity::warning : Severity::info, line);
}

}  // namespace

SiteSet read_sites(const std::string& dataset_name, const ReadOptions& options) {
  const auto read_start = std::chrono::steady_clock::now();
  grid::require_level(options.level);
  GDALAllRegister();

  // --- the dataset and its layers ---------------------------------------------------------------
  gdal::ErrorCapture errors;
  const OgrSource source = open_source(dataset_name, options, errors);

  // --- each layer, its sites after the layer before's -------------------------------------------
  SiteSet out;
  // QTMV_TRACE=read: the parts' times (for tuning).
  const bool trace = trace_enabled(TraceStage::read);
  const ScopedDefaultThreads thread_limit(options.threads);  // the claims' sorts too
  ReadTotals totals(out, options, thread_count(options.threads), trace);
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  report_progress(options.progress, 0.0, "reading sites");
  // A tile job: the features near its tile, where the source can say which they are.
  TileSelection selection;
  if (options.tile_range.end != 0) {
    selection = select_tile_features(source, options, errors, wgs84);
    out.subset = selection.used;
    out.source_features = selection.source_features;
    trace_printf(TraceStage::read, "tile's sites: %s%s", selection.used ? "" : "every feature read: ",
                 selection.why.c_str());
  }
  for (std::size_t layer_number = 0; layer_number < source.layers.size(); ++layer_number) {
    read_layer(source, layer_number, options, errors, wgs84, totals,
               selection.used ? &selection.features[layer_number] : nullptr);
  }
  report_progress(options.progress, 1.0, "reading sites");

  // --- claims, counts, summary --------------------------------------------------------------------
  sum_up(totals, source.describe(), options, read_start);
  return out;
}

}  // namespace qtmv::sites
