#include "voronoi.hpp"

#include <algorithm>
#include <future>
#include <memory>
#include <string>

#include <cpl_conv.h>

#include "common/config_option.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "label/device_startup.hpp"
#include "pipeline/database_output.hpp"
#include "pipeline/part_index.hpp"
#include "pipeline/run_plan.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/stages.hpp"
#include "sites/feature_count.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_writer.hpp"

namespace qtmv {

namespace {

/// -merge PARTS -of VRT: the parts' index, all or nothing; no source is read, nothing labelled.
VoronoiSummary run_part_index(const std::string& destination, const VoronoiOptions& options) {
  const double t_start = now_seconds();
  if (options.tile_count > 0) throw VoronoiError("-tile and -merge: a run labels one tile, or merges all of them");
  const std::vector<std::string> files = pipeline::part_files(options.merge);
  pipeline::StagedOutput output(destination, options.overwrite);
  const pipeline::PartIndexSummary index = pipeline::write_part_index(files, output.begin(), destination);
  output.commit();
  VoronoiSummary summary;
  summary.driver = "VRT";
  summary.level = index.level;
  summary.cells = grid::cell_count(index.level);
  summary.device = "index of " + std::to_string(index.parts) + " parts";
  summary.total_seconds = summary.write_seconds = now_seconds() - t_start;
  std::string rows;
  for (const auto& [layer, count] : index.layers) rows += (rows.empty() ? "" : ", ") + layer + " " + std::to_string(count);
  summary.raster = !index.raster.empty();
  tell(options.messages, Severity::info,
       "'" + destination + "': index of " + std::to_string(index.parts) + " parts of level " + std::to_string(index.level) +
           (summary.raster ? " (raster: " + index.raster + ")" : " (rows: " + rows + ")"));
  return summary;
}

/// A part's identity (its metadata: pipeline/part_index.hpp).
std::vector<std::pair<std::string, std::string>> part_metadata(const pipeline::RunPlan& plan, const std::string& source,
                                                               const VoronoiOptions& options) {
  pipeline::PartIdentity part;
  part.level = plan.level;
  part.rule = options.rule;
  part.index = plan.tile_index;
  part.count = plan.tile_count;
  part.source = source;
  part.source_fingerprint = pipeline::source_fingerprint(source, options.read);
  if (plan.format.raster) {
    // The bands as the writer will name them; the whole raster and the part's rows.
    part.raster = true;
    for (const write::RasterBand band : write::raster_bands(plan.raster, plan.label.want_distance)) {
      part.layers.emplace_back(write::raster_band_description(band));
    }
    const write::RasterSize size = write::raster_size(plan.level, plan.raster);
    part.layout = plan.raster.layout == write::RasterGrid::Layout::lonlat ? "lonlat" : "qtm";
    part.width = size.width;
    part.height = size.height;
    part.first_row = plan.raster.first_row;
    part.end_row = plan.raster.first_row + plan.raster.part_rows;
    return pipeline::part_metadata(part);
  }
  for (const std::string& layer : plan.vector.layers) {
    if (std::find(part.layers.begin(), part.layers.end(), layer) == part.layers.end()) part.layers.push_back(layer);
  }
  return pipeline::part_metadata(part);
}

}  // namespace

VoronoiSummary run_voronoi(const std::string& source, const std::string& destination, const VoronoiOptions& options) {
  const double t_start = now_seconds();
  const ScopedDefaultThreads thread_limit(options.threads);  // every stage's sorts and loops too
  // The run switches (QTMV_TRACE, QTMV_FAULT_*) are GDAL configuration options (--config or the
  // environment), and the trace channel's lines are the run's messages.
  set_config_lookup(&CPLGetConfigOption);
  const ScopedTraceSink trace_sink(options.messages);
  if (pipeline::writes_part_index(destination, options)) return run_part_index(destination, options);
  const bool tile_job = options.tile_count > 0 && !options.part;  // a tile product; a part is written as a dataset
  // The GPUs are counted and their contexts made (tenths of a second a process: much of a small
  // run, and of every tile job) while the run is planned and its sites read; a merge makes none.
  // -device auto starts them only once its estimate picks a GPU (a run the CPU does faster never
  // pays the driver's start): before the read when the plan alone says so, else after it.
  std::unique_ptr<label::DeviceStartup> devices;
  const auto start_devices = [&] {
    if (!devices) devices = std::make_unique<label::DeviceStartup>(options.device, /*contexts=*/options.merge.empty());
  };
  const bool automatic = options.device == "auto";
  if (!automatic) start_devices();
  // Every check before any work; the devices' as soon as they are counted.
  pipeline::RunPlan plan = options.tile_count > 0 ? pipeline::plan_tile_job(destination, options) : pipeline::plan_run(destination, options);
  if (!plan.level_note.empty()) tell(options.messages, Severity::info, plan.level_note);
  label::AutoDevice auto_choice;  // with no sites yet: the least work the plan can take
  if (automatic) auto_choice = pipeline::estimate_auto_device(plan, 0, 0);
  if (auto_choice.gpu) start_devices();
  if (automatic && !auto_choice.gpu && options.merge.empty()) {
    // A source that tells its size at once (a count, a CSV's bytes) may show the GPU worth its
    // start before the read: it then starts beside the read, as for -device cuda, instead of
    // after it. The choice itself waits for the sites read.
    const std::uint64_t guess = sites::feature_count_guess(source, options.read);
    if (guess > 0 && pipeline::estimate_auto_device(plan, guess, guess).gpu) {
      trace_printf(TraceStage::label, "auto: the GPU started beside the read (%llu features guessed before it)",
                   static_cast<unsigned long long>(guess));
      start_devices();
    }
  }
  pipeline::StagedOutput output(destination, options.overwrite,
                                pipeline::open_database_output(destination, options.overwrite, plan));
  pipeline::RunProgress progress(options.progress);
  VoronoiSummary summary;
  summary.driver = plan.format.driver;
  summary.raster = plan.format.raster;
  summary.level = plan.level;
  summary.cells = grid::cell_count(plan.level);
  summary.tile_index = options.tile_index;
  summary.tile_count = options.tile_count;

  double t0 = now_seconds();
  // A -device naming a GPU this host lacks stops the read at its first report after the count,
  // and its error comes before any of the read's.
  bool devices_checked = false;
  const auto devices_fit = [&] {
    if (devices_checked || !devices || !devices->counted()) return true;
    devices_checked = true;
    try {
      pipeline::check_devices(plan, devices->device_count());
    } catch (const VoronoiError&) {
      return false;
    }
    return true;
  };
  sites::SiteSet sites;
  try {
    sites = pipeline::read_stage(source, options, plan, progress, devices_fit);
  } catch (...) {
    if (devices) pipeline::check_devices(plan, devices->device_count());
    throw;
  }
  if (automatic) {
    const label::LabelInput input = sites.geometry.input();
    const std::uint64_t candidates =
        (options.rule == label::Rule::exact ? input.piece_count : input.site_cell_count) + input.fixed_cell_count;
    auto_choice = pipeline::estimate_auto_device(plan, sites.table.sites.size(), candidates);
    if (auto_choice.gpu) start_devices();
    trace_printf(TraceStage::label, "auto: %s", auto_choice.reason().c_str());
  }
  const int cuda_devices = devices ? devices->device_count() : 0;
  if (automatic) pipeline::settle_auto_device(plan, auto_choice, cuda_devices);
  pipeline::settle_devices(plan, options, cuda_devices);
  if (devices) devices->wait();
  summary.features = sites.summary.features;
  summary.sites = sites.summary.sites;
  summary.skipped = sites.summary.skipped;
  summary.invalid_polygons = sites.summary.invalid_polygons;
  summary.repaired_polygons = sites.summary.repaired_polygons;
  summary.rasterise_seconds = sites.summary.rasterise_seconds;
  summary.read_seconds = now_seconds() - t0;

  t0 = now_seconds();
  // A merge joins the tile jobs' products instead of labelling.
  const pipeline::LabelledLevel labels =
      plan.merge_files.empty() ? pipeline::label_stage(sites, options, plan, progress, &summary.sites_without_cell)
                               : pipeline::merge_stage(source, sites, options, plan, progress, &summary.sites_without_cell);
  summary.device = automatic && plan.merge_files.empty()
                       ? pipeline::auto_device_summary(labels.device, auto_choice, cuda_devices)
                       : labels.device;
  summary.prepare_seconds = labels.prepare_seconds;
  summary.label_seconds = now_seconds() - t0;

  t0 = now_seconds();
  // A raster's labels are made strip by strip as it is written: that time counts as labelling.
  double strip_label_seconds = 0;
  if (tile_job) {
    pipeline::write_tile_stage(output.begin(), destination, labels, sites, options, plan);
  } else {
    if (plan.vector.part) plan.vector.metadata = part_metadata(plan, source, options);
    if (plan.part && plan.format.raster) plan.raster.metadata = part_metadata(plan, source, options);
    strip_label_seconds = pipeline::write_stage(output.begin(), destination, labels, sites, plan, progress,
                                                options.messages, &summary.sites_without_cell);
  }
  summary.label_seconds += strip_label_seconds;
  output.commit();
  summary.write_seconds = now_seconds() - t0 - strip_label_seconds;
  summary.total_seconds = now_seconds() - t_start;
  tell(options.messages, Severity::info, summary.line());
  return summary;
}

}  // namespace qtmv
