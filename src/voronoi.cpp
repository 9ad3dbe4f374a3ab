#include "common/device_spec.hpp"
#include "common/host_info.hpp"
#include "voronoi.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <sstream>
#include <system_error>
#include <utility>
#include <vector>

#include "gdal/error_capture.hpp"
#include "pipeline/staged_output.hpp"
#include "grid/qtm_checks.hpp"
#include "sites/fid_list.hpp"
#include "sites/ogr_site_reader.hpp"
#include "write/output_size.hpp"
#include "write/raster_writer.hpp"
#include "write/vector_writer.hpp"

namespace qtmv {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string seconds(double s) {
  char text[64];
  std::snprintf(text, sizeof text, "%.2f s", s);
  return text;
}

// The labeller hands its outputs over in tiles and checks for an interrupt between them; on the
// CPU, tiles of 64 MiB (about 7 million cells) keep that check under a second.
constexpr std::uint64_t kCpuTileBytes = std::uint64_t{64} << 20;

bool labels_on_cpu(const label::LabelOptions& options) {
  const DeviceSpec device = parse_device_spec(options.device);
  return device.kind == DeviceSpec::Kind::cpu ||
         (device.kind == DeviceSpec::Kind::automatic && label::cuda_device_count() == 0);
}

// The tile limit the pipeline passes to the labeller (0: the labeller's own, a quarter of RAM).
std::uint64_t tile_limit(const label::LabelOptions& options) {
  if (options.memory_limit_bytes != 0) return options.memory_limit_bytes;
  return labels_on_cpu(options) ? kCpuTileBytes : 0;
}

// Maps each part's progress onto a slice of the whole run and remembers a request to stop.
class Progress {
 public:
  explicit Progress(const ProgressFunc& user) : user_(user) {}
  bool report(double begin, double end, double fraction, const char* stage) {
    if (cancelled_) return false;
    if (!user_) return true;
    fraction = std::min(1.0, std::max(0.0, fraction));
    if (!user_(begin + (end - begin) * fraction, stage)) cancelled_ = true;
    return !cancelled_;
  }
  bool cancelled() const { return cancelled_; }

 private:
  const ProgressFunc& user_;
  bool cancelled_ = false;
};

// Where each stage's slice of the whole run ends (fractions), in proportion to its expected
// time per cell at level 11 on the 2-core development machine (bench/RESULTS.md, "qtmvoronoi end to end"):
// labelling on the CPU ~50 ns (a GPU far less), vector output ~400 ns (the cells layer ~300 ns
// more), a raster ~100 ns. Reading gets a fixed 5%.
struct StageEnds {
  double read, label;
};

StageEnds stage_ends(bool raster, bool cells_layer, bool label_on_cpu) {
  const double label = label_on_cpu ? 50 : 5;
  const double write = raster ? 100 : 400 + (cells_layer ? 300 : 0);
  const double read = 0.05;
  return {read, read + (1 - read) * label / (label + write)};
}

}  // namespace

std::string VoronoiSummary::line() const {
  std::ostringstream s;
  s << sites << " site" << (sites == 1 ? "" : "s") << " read, " << skipped << " skipped";
  if (invalid_polygons > 0) {
    s << ", " << invalid_polygons << " with an invalid polygon";
    if (repaired_polygons > 0) s << " (" << repaired_polygons << " repaired)";
  }
  s << "; level " << level << ", "
    << cells << " cells; " << device << "; read " << seconds(read_seconds) << " (rasterise " << seconds(rasterise_seconds) << "), label " << seconds(label_seconds)
    << " (prepare " << seconds(prepare_seconds) << "), write " << seconds(write_seconds) << "; total "
    << seconds(total_seconds);
  return s.str();
}

std::uint64_t estimate_run_memory(int level, const label::LabelOptions& label_options) {
  grid::require_level(level);
  const label::MemoryEstimate e = label::estimate_output_memory(level, label_options);
  // The labeller's tile buffer: its limit, a quarter of RAM by default, at most 2^28 cells.
  std::uint64_t limit = tile_limit(label_options);
  if (limit == 0) limit = host_ram_bytes() / 4;
  const std::uint64_t tile_cells =
      std::min({e.cells, std::max<std::uint64_t>(1, limit / e.bytes_per_cell), std::uint64_t{1} << 28});
  return e.output_bytes + tile_cells * e.bytes_per_cell;
}

VoronoiSummary run_voronoi(const std::string& source, const std::string& destination, const VoronoiOptions& options) {
  const double t_start = now_seconds();
  auto say = [&](Severity severity, const std::string& message) {
    if (options.messages) options.messages(severity, message);
  };
  const int level = options.level;
  try {
    grid::require_level(level);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-level: ") + e.what());
  }

  // --- options, format, destination and memory, before any work ---------------------------------
  const OutputFormat format = choose_output_format(destination, options.format, options.kind);
  write::VectorOptions vector_options;
  static_cast<write::VectorLayers&>(vector_options) = options.vector;
  write::RasterOptions raster_options;
  static_cast<write::RasterGrid&>(raster_options) = options.raster;
  vector_options.driver = raster_options.driver = format.driver;
  if (format.raster) {
    if (!options.vector.dataset_options.empty() || !options.vector.layer_options.empty()) {
      throw VoronoiError("-dsco and -lco are for vector output; " + format.driver + " output is a raster: use -co");
    }
    try {
      write::raster_size(level, raster_options);  // -tr, -ts and -raster checked as the writer will
    } catch (const write::WriteError& e) {
      throw VoronoiError(e.what());
    }
  } else if (!options.raster.creation_options.empty()) {
    throw VoronoiError("-co is for raster output; " + format.driver + " output is vector: use -lco or -dsco");
  }
  if (!format.raster) {
    if (const std::string problem = write::check_layer_names(vector_options.layers); !problem.empty()) {
      throw VoronoiError("-layers: " + problem);
    }
    // A driver without multi-layer files (Shapefile, GeoJSON, FlatGeobuf, CSV...) writing to one
    // file of its own extension holds one layer: say so now, not after all the work.
    GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format.driver.c_str());
    const bool multi_layer = driver && CPLTestBool(CSLFetchNameValueDef(driver->GetMetadata(),
                                                                        GDAL_DCAP_MULTIPLE_VECTOR_LAYERS, "NO"));
    const std::string extension = lower(CPLGetExtension(destination.c_str()));
    if (!multi_layer && vector_options.layers.size() > 1 && !extension.empty()) {
      throw VoronoiError("'" + destination + "': a " + format.driver + " file holds one layer: use -layers with one of " +
                         "them, or name a directory (for drivers that write one file per layer there) or a format " +
                         "such as GPKG");
    }
    // CSV keeps no geometry unless asked to: keep it, as WKT.
    const bool geometry_option = std::any_of(vector_options.layer_options.begin(), vector_options.layer_options.end(),
                                             [](const std::string& o) { return lower(o).rfind("geometry=", 0) == 0; });
    if (format.driver == "CSV" && !geometry_option) vector_options.layer_options.push_back("GEOMETRY=AS_WKT");
  }
  DeviceSpec device;
  try {
    device = parse_device_spec(options.device);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-device: ") + e.what());
  }
  label::LabelOptions label_options;
  label_options.rule = options.rule;
  label_options.device = options.device;
  label_options.algorithm = options.algorithm;
  label_options.threads = options.threads;
  const bool wants_cells_layer =
      std::find(vector_options.layers.begin(), vector_options.layers.end(), "cells") != vector_options.layers.end();
  label_options.want_distance = format.raster || wants_cells_layer;
  label_options.want_boundary = true;
  label_options.memory_limit_bytes = tile_limit(label_options);

  const std::uint64_t need = estimate_run_memory(level, label_options);
  const std::uint64_t ram = host_ram_bytes();
  const std::uint64_t allowed = options.memory_limit_bytes ? options.memory_limit_bytes : ram / 10 * 8;
  if (need > allowed) {
    const label::MemoryEstimate e = label::estimate_output_memory(level, label_options);
    throw VoronoiError("level " + std::to_string(level) + " needs about " + format_gib(double(need)) + " for its " +
                       std::to_string(e.cells) + " cells (" + std::to_string(e.bytes_per_cell) +
                       " bytes each, and the labeller's tiles), more than the " + format_gib(double(allowed)) +
                       " allowed (80% of this host's " + format_gib(double(ram)) + " of RAM): choose a lower -level");
  }

  // A GPU asked for and missing fails now, not after the read.
  if (device.kind == DeviceSpec::Kind::cuda) {
    const int gpus = label::cuda_device_count();
    if (device.index >= gpus) {
      throw VoronoiError("-device " + label_options.device + ": " +
                         (gpus == 0 ? std::string("no usable CUDA GPU found")
                                    : "this host has " + std::to_string(gpus) + " CUDA device(s)") +
                         "; use -device cpu or auto");
    }
  }

  // An output its file system cannot hold fails now, not after the work (GDAL's GeoTIFF driver
  // checks the same, late, and only uncompressed files).
  if (options.check_disk_space) {
    try {
      write::check_disk_space(destination,
                              format.raster ? write::estimate_raster_size(level, raster_options, label_options.want_distance)
                                            : write::estimate_vector_size(level, vector_options),
                              format.raster ? "raster" : "cells layer");
    } catch (const write::WriteError& e) {
      throw VoronoiError(e.what());
    }
  }

  pipeline::StagedOutput output(destination, options.overwrite);
  Progress progress(options.progress);
  const StageEnds ends = stage_ends(format.raster, wants_cells_layer, labels_on_cpu(label_options));
  VoronoiSummary summary;
  summary.driver = format.driver;
  summary.raster = format.raster;
  summary.level = level;
  summary.cells = grid::cell_count(level);

  // --- read ----------------------------------------------------------------------------------------
  double t0 = now_seconds();
  sites::ReadOptions read_options;
  static_cast<sites::SourceOptions&>(read_options) = options.read;
  read_options.level = level;
  read_options.distance = options.rule;
  read_options.progress = [&](double f, const char* stage) { return progress.report(0.0, ends.read, f, stage); };
  // The reader's count of sites without a cell comes before labelling; the pipeline reports the
  // final one (below) instead.
  read_options.warn_sites_without_cell = false;
  read_options.messages = [&](Severity severity, const std::string& message) { say(severity, message); };
  sites::SiteSet sites;
  try {
    if (!progress.report(0.0, ends.read, 0.0, "read")) throw Interrupted();
    sites = sites::read_sites(source, read_options);
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    if (progress.cancelled()) throw Interrupted();
    throw VoronoiError(e.what());
  }
  summary.features = sites.summary.features;
  summary.sites = sites.summary.sites;
  summary.skipped = sites.summary.skipped;
  summary.invalid_polygons = sites.summary.invalid_polygons;
  summary.repaired_polygons = sites.summary.repaired_polygons;
  summary.read_seconds = now_seconds() - t0;
  summary.rasterise_seconds = sites.summary.rasterise_seconds;

  // --- label ---------------------------------------------------------------------------------------
  t0 = now_seconds();
  const std::uint64_t cells = summary.cells;
  std::vector<std::int32_t> site;
  std::vector<float> distance;
  std::vector<std::uint8_t> boundary;
  try {
    site.resize(cells);
    if (label_options.want_distance) distance.resize(cells);
    if (label_options.want_boundary) boundary.resize(cells);
  } catch (const std::bad_alloc&) {
    throw VoronoiError("out of memory for the labels of level " + std::to_string(level) + " (" + format_gib(double(need)) + ")");
  }
  // The labeller reports between tiles, on this thread; false stops it with Interrupted.
  label_options.progress = [&](double f, const char* stage) { return progress.report(ends.read, ends.label, f, stage); };
  label_options.messages = [&](Severity severity, const std::string& message) { say(severity, message); };
  label::LabelStats stats;
  try {
    stats = label::label_cells(sites.geometry.input(), label_options, [&](const label::LabelTile& tile) {
      std::memcpy(site.data() + tile.first, tile.site, tile.count * sizeof(std::int32_t));
      if (tile.distance_m) std::memcpy(distance.data() + tile.first, tile.distance_m, tile.count * sizeof(float));
      if (tile.boundary) std::memcpy(boundary.data() + tile.first, tile.boundary, tile.count);
    });
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    throw VoronoiError(std::string("labelling failed: ") + e.what());
  }
  summary.device = stats.device;
  summary.prepare_seconds = stats.prepare_seconds;

  // Sites left without a cell still get their row; say which.
  std::vector<std::uint64_t> count(sites.table.sites.size(), 0);
  for (std::uint64_t c = 0; c < cells; ++c) ++count[static_cast<std::size_t>(site[c])];
  sites::FidList without_cell;
  for (std::size_t s = 0; s < count.size(); ++s) {
    sites.table.sites[s].has_own_cell = count[s] > 0;
    if (count[s] == 0) without_cell.add(sites.table.sites[s].fid);
  }
  summary.sites_without_cell = without_cell.count();
  if (without_cell.count() > 0) {
    say(Severity::warning, std::to_string(without_cell.count()) + " site(s) got no cell of their own at level " +
                               std::to_string(level) + " (FIDs " + without_cell.text() + ")" +
                               (format.raster ? "" : "; they keep their row, with an empty geometry"));
  }
  summary.label_seconds = now_seconds() - t0;

  // --- write ---------------------------------------------------------------------------------------
  t0 = now_seconds();
  const std::string& path = output.begin();
  const write::CellLabels labels{level, site.data(), distance.empty() ? nullptr : distance.data(),
                                 boundary.empty() ? nullptr : boundary.data()};
  const write::ProgressFunc write_progress = [&](double f, const char* stage) {
    return progress.report(ends.label, 1.0, f, stage);
  };
  try {
    const pipeline::RenameInMessages name_the_destination(path, destination);
    if (!progress.report(ends.label, 1.0, 0.0, "write")) throw Interrupted();
    if (format.raster) {
      raster_options.progress = write_progress;
      write::write_raster(path, labels, sites.table, raster_options);
    } else {
      vector_options.progress = write_progress;
      // A temporary file, renamed into place only after a clean close, needs no durability
      // while it is written: no fsync, no rollback journal (nothing is rolled back; a failed
      // write is removed). Only where the user has not set these, and never for a direct write.
      const bool temporary = path != destination;
      std::unique_ptr<CPLConfigOptionSetter> no_sync, no_journal;
      if (temporary) {
        no_sync = std::make_unique<CPLConfigOptionSetter>("OGR_SQLITE_SYNCHRONOUS", "OFF", true);
        no_journal = std::make_unique<CPLConfigOptionSetter>("OGR_SQLITE_JOURNAL", "OFF", true);
      }
      write::write_vector(path, labels, sites.table, vector_options);
    }
    // A stop asked for during the close is honoured too: nothing is renamed yet.
    if (!progress.report(ends.label, 1.0, 1.0, "write")) throw Interrupted();
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    if (progress.cancelled()) throw Interrupted();
    std::string message = e.what();
    pipeline::replace_all(message, path, destination);  // name the destination, not the temporary file
    throw VoronoiError(message);
  }
  output.commit();
  summary.write_seconds = now_seconds() - t0;
  summary.total_seconds = now_seconds() - t_start;
  say(Severity::info, summary.line());
  return summary;
}

}  // namespace qtmv
