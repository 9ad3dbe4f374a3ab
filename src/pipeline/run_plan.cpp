#include "pipeline/run_plan.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal_priv.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "common/device_spec.hpp"
#include "common/visible_devices.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "grid/qtm_checks.hpp"
#include "label/label_session.hpp"
#include "label/outline_cells.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "pipeline/tile_product.hpp"
#include "write/output_size.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_writer.hpp"
#include "write/region_tracer.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::pipeline {

namespace {

// A lon/lat raster's pixel takes the site of the cell holding its centre: with cells this many
// times finer than a pixel (in latitude), few pixels name a site that is not the nearest to their
// centre (country centres at 0.1 degrees: 0.39% at level 9, 0.012% at level 14).
constexpr double kCellsPerPixel = 4.0;

/// For a lon/lat raster sized by -tr or -ts with no -level: sets plan.level to the level whose
/// rows of cells (90 / 2^L degrees) are kCellsPerPixel times finer than a pixel, and says so.
std::string choose_pixel_level(RunPlan& plan) {
  const write::RasterGrid& grid = plan.raster;
  const bool sized = grid.x_resolution != 0 || grid.y_resolution != 0 || grid.width != 0 || grid.height != 0;
  if (grid.layout != write::RasterGrid::Layout::lonlat || !sized) return "";
  write::RasterSize size;
  try {
    size = write::raster_size(plan.level, plan.raster);
  } catch (const write::WriteError&) {
    return "";  // the raster's own checks report it
  }
  const double pixel = std::min(size.x_resolution, size.y_resolution);  // degrees
  int level = 0;
  while (level < grid::kMaxLevel && 90.0 / static_cast<double>(grid::rows_per_octant(level)) > pixel / kCellsPerPixel) {
    ++level;
  }
  plan.level = level;
  char text[256];
  std::snprintf(text, sizeof text,
                "level %d chosen for pixels of %.6g x %.6g degrees: cells of %.3g degrees, about %.0f times finer "
                "(-level sets another)",
                level, size.x_resolution, size.y_resolution, 90.0 / static_cast<double>(grid::rows_per_octant(level)),
                kCellsPerPixel);
  return text;
}

// The labeller hands its outputs over in tiles and checks for an interrupt between them; on the
// CPU, tiles of 64 MiB (about 7 million cells) keep that check under a second.
constexpr std::uint64_t kCpuTileBytes = std::uint64_t{64} << 20;

// Host bytes per outline cell at the run's peak: the cell itself (label::OutlineCell, 12) and the
// most held beside the cells: the CPU outline pass's join (its threads' lists, about 1.6 listings
// a cell, a sort's spare of one list, and the result: up to 2.6 cells' worth more), the
// regions' tracer (RegionTracer::kBytesPerOutlineCell, 4), the Voronoi edges (32 bytes per cell
// edge between sites, the edges and their sort's spare, about 0.7 of them per outline cell); the
// margin covers the rows in flight and the per-site arrays. (Before the cells were packed and the tracer's lists made in place,
// the regions' peak alone held 32 bytes a cell.)
constexpr std::uint64_t kBytesPerOutlineCell = 4 * sizeof(label::OutlineCell);
static_assert(kBytesPerOutlineCell >= sizeof(label::OutlineCell) + write::RegionTracer::kBytesPerOutlineCell,
              "the estimate covers the regions' tracer");

// Whether `device` (a -device value) labels on the CPU, with `cuda_devices` found on this host;
// -1: not counted yet, when "auto" is taken as the CPU (its smaller tiles: the check before the
// read is then the lenient one, and the one after it, with the devices counted, exact).
bool labels_on_cpu(const std::string& device, int cuda_devices) {
  const DeviceSpec spec = parse_device_spec(device);
  return spec.kind == DeviceSpec::Kind::cpu || (spec.kind == DeviceSpec::Kind::automatic && cuda_devices <= 0);
}

// The tile limit (bytes) the pipeline passes to the labeller: `asked` (-memory), else the CPU's
// tiles, else 0 (the labeller's own, a quarter of RAM).
std::uint64_t tile_limit(std::uint64_t asked, const std::string& device, int cuda_devices) {
  if (asked != 0) return asked;
  return labels_on_cpu(device, cuda_devices) ? kCpuTileBytes : 0;
}

// The read stage's slice of a run's progress (fraction): a fixed 5%.
constexpr double kReadEnd = 0.05;

// Where the read and label stages' slices of the run end (fractions), in proportion to their
// expected time per cell at level 11 on the 2-core development machine (bench/RESULTS.md,
// "qtmvoronoi end to end"): labelling on the CPU ~50 ns (a GPU far less), a raster ~100 ns,
// the cells layer ~300 ns; the outline products cost little per cell. Reading gets a fixed 5%.
void set_stage_ends(RunPlan& plan) {
  const bool cpu = labels_on_cpu(plan.label.device, plan.cuda_devices);
  // A raster's labels are made on the CPU strip by strip while it is written (~50 ns a cell);
  // the label stage finds its outlines (which sites got a cell) and builds the session's tree.
  const double label = plan.format.raster ? (cpu ? 12 : 3) : (cpu ? 10 : 2) + (plan.cells_layer ? (cpu ? 50 : 5) : 0);
  const double write = plan.format.raster ? 150 : 20 + (plan.cells_layer ? 300 : 0);
  plan.read_end = kReadEnd;
  plan.label_end = plan.read_end + (1 - plan.read_end) * label / (label + write);
}

void check_vector_destination(const std::string& destination, RunPlan& plan) {
  write::VectorOptions& vector = plan.vector;
  if (const std::string problem = write::check_layer_names(vector.layers); !problem.empty()) {
    throw VoronoiError("-layers: " + problem);
  }
  // A driver without multi-layer files (Shapefile, GeoJSON, FlatGeobuf, CSV...) writing to one
  // file of its own extension holds one layer: say so now, not after all the work.
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(plan.format.driver.c_str());
  const bool multi_layer = driver && CPLTestBool(CSLFetchNameValueDef(driver->GetMetadata(),
                                                                      GDAL_DCAP_MULTIPLE_VECTOR_LAYERS, "NO"));
  const std::string extension = CPLGetExtension(destination.c_str());
  if (!multi_layer && vector.layers.size() > 1 && !extension.empty()) {
    throw VoronoiError("'" + destination + "': a " + plan.format.driver + " file holds one layer: use -layers with one of " +
                       "them, or name a directory (for drivers that write one file per layer there) or a format " +
                       "such as GPKG");
  }
  // A driver's layer option the user did not give: set to the project's default.
  const auto default_layer_option = [&](const char* driver, const char* name, const char* value) {
    if (plan.format.driver != driver) return;
    const std::string prefix = std::string(name) + "=";
    if (std::none_of(vector.layer_options.begin(), vector.layer_options.end(),
                     [&](const std::string& o) { return STARTS_WITH_CI(o.c_str(), prefix.c_str()); })) {
      vector.layer_options.push_back(prefix + value);
    }
  };
  // CSV keeps no geometry unless asked to: keep it, as WKT.
  default_layer_option("CSV", "GEOMETRY", "AS_WKT");
  // A shapefile's text is ISO-8859-1 unless told: names beyond Latin-1 would be mangled. UTF-8,
  // as the sources' text is to OGR.
  default_layer_option("ESRI Shapefile", "ENCODING", "UTF-8");
  plan.cells_layer = std::find(vector.layers.begin(), vector.layers.end(), "cells") != vector.layers.end();
}

// A plan of options.level, checked.
RunPlan plan_level(const VoronoiOptions& options) {
  RunPlan plan;
  plan.level = options.level == VoronoiOptions::kLevelFromOutput ? label::kDefaultLevel : options.level;
  try {
    grid::require_level(plan.level);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-level: ") + e.what());
  }
  return plan;
}

// The labeller's options; the devices are settled once counted (settle_devices).
void plan_labeller(RunPlan& plan, const VoronoiOptions& options, bool want_distance) {
  try {
    parse_device_spec(options.device);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-device: ") + e.what());
  }
  label::LabelOptions& label_options = plan.label;
  label_options.rule = options.rule;
  label_options.device = options.device;
  label_options.algorithm = options.algorithm;
  label_options.threads = options.threads;
  label_options.want_distance = want_distance;
  label_options.want_boundary = true;
  label_options.memory_limit_bytes = tile_limit(options.memory_limit_bytes, options.device, plan.cuda_devices);
}

// A raster destination's plan (a whole run's or a part's): its grid, bands and type checked as the
// writer will, the level from the pixels where -level is not given, the writer's strip.
void plan_raster(RunPlan& plan, const VoronoiOptions& options) {
  static_cast<write::RasterGrid&>(plan.raster) = options.raster;
  plan.raster.driver = plan.format.driver;
  if (options.level == VoronoiOptions::kLevelFromOutput) plan.level_note = choose_pixel_level(plan);
  if (!options.vector.dataset_options.empty() || !options.vector.layer_options.empty()) {
    throw VoronoiError("-dsco and -lco are for vector output; " + plan.format.driver + " output is a raster: use -co");
  }
  if (options.read.layers.size() > 1) {
    throw VoronoiError("-l names " + std::to_string(options.read.layers.size()) +
                       " layers: a raster's FID band cannot tell their sites apart; write vector output, whose "
                       "rows name each site's layer");
  }
  if (options.vector.ring_vertices != write::VectorLayers::Vertices::automatic) {
    throw VoronoiError("-vertices is for the regions of vector output; " + plan.format.driver + " output is a raster");
  }
  if (options.algorithm == label::Algorithm::brute) {
    throw VoronoiError("-algorithm brute is for vector output; " + plan.format.driver +
                       " output is a raster, labelled strip by strip from the pruned tree (the same labels)");
  }
  try {
    write::raster_size(plan.level, plan.raster);  // -tr, -ts and -raster checked as the writer will
    write::check_raster_data_type(plan.raster.data_type);
    write::raster_bands(plan.raster, true);  // each band once
  } catch (const write::WriteError& e) {
    throw VoronoiError(e.what());
  }
  // The writer's strip follows the memory the run may use.
  if (options.memory_limit_bytes != 0) {
    plan.raster.strip_bytes = std::min<std::uint64_t>(write::kDefaultStripBytes, options.memory_limit_bytes / 4);
  }
}

// An output its file system cannot hold fails now, not after the work (GDAL's GeoTIFF driver
// checks the same, late, and only uncompressed files). (A database's free space is not the
// destination's directory's.) A raster part's is its rows'.
void check_destination_space(const std::string& destination, const RunPlan& plan, const VoronoiOptions& options) {
  if (!options.check_disk_space || is_database_driver(plan.format.driver)) return;
  try {
    write::check_disk_space(destination,
                            plan.format.raster ? write::estimate_raster_size(plan.level, plan.raster, plan.label.want_distance)
                                               : write::estimate_vector_size(plan.level, plan.vector),
                            plan.format.raster ? "raster" : "cells layer");
  } catch (const write::WriteError& e) {
    throw VoronoiError(e.what());
  }
}

// Refuses the raster's options for vector output.
void refuse_raster_options(const RunPlan& plan, const VoronoiOptions& options) {
  if (!options.raster.data_type.empty()) {
    throw VoronoiError("-ot is for raster output; " + plan.format.driver + " output is vector");
  }
  if (!options.raster.creation_options.empty()) {
    throw VoronoiError("-co is for raster output; " + plan.format.driver + " output is vector: use -lco or -dsco");
  }
  if (!options.raster.bands.empty()) {
    throw VoronoiError("-bands is for raster output; " + plan.format.driver + " output is vector: use -layers");
  }
}

// A raster's labels: only those of its bands (no distances without the distance band, no
// boundary flags without the boundary band).
void plan_raster_labels(RunPlan& plan, const VoronoiOptions& options) {
  const auto has = [&](write::RasterBand band) { return plan.raster.bands.empty() || write::has_band(plan.raster.bands, band); };
  plan_labeller(plan, options, has(write::RasterBand::distance));
  plan.label.want_boundary = has(write::RasterBand::boundary);
}

}  // namespace

std::uint64_t estimate_run_memory(const RunPlan& plan, std::uint64_t sites) {
  const int level = plan.level;
  const label::MemoryEstimate dense = label::estimate_output_memory(level, plan.label);
  // The labeller's tile buffer: its limit, a quarter of RAM by default, at most 2^28 cells.
  std::uint64_t limit = plan.label.memory_limit_bytes;
  if (limit == 0) limit = host_ram_bytes() / 4;
  const std::uint64_t tile_cells =
      std::min({dense.cells, std::max<std::uint64_t>(1, limit / dense.bytes_per_cell), std::uint64_t{1} << 28});
  const std::uint64_t tile_bytes = tile_cells * dense.bytes_per_cell;
  // Outline cells: the row ends, and boundary cells along the Voronoi edges (label/auto_device.hpp).
  double outline = label::expected_outline_cells(level, sites);
  // A tile job holds its part of them (its rows, about its share of the edges).
  if (plan.label.range.end != 0) outline *= static_cast<double>(plan.label.range.size()) / static_cast<double>(dense.cells);
  if (plan.format.raster) {
    // The labelling session's tree (its jump table grows with the level, up to 256 MiB) and the
    // writer's strip: never every cell's labels.
    std::uint64_t strip = 0;
    try {
      strip = write::raster_buffer_bytes(level, plan.raster, plan.label.want_distance);
    } catch (const write::WriteError&) {
      strip = write::kDefaultStripBytes;  // bad sizes are reported by plan_run
    }
    return label::session_jump_table_bytes(level) + strip;
  }
  return static_cast<std::uint64_t>(outline) * kBytesPerOutlineCell + tile_bytes;
}

void check_run_memory(const RunPlan& plan, std::uint64_t memory_limit_bytes, std::uint64_t sites) {
  const std::uint64_t need = estimate_run_memory(plan, sites);
  const std::uint64_t ram = host_ram_bytes();
  const std::uint64_t allowed = memory_limit_bytes ? memory_limit_bytes : ram / 10 * 8;
  if (need <= allowed) return;
  throw VoronoiError("level " + std::to_string(plan.level) + (sites ? " with " + std::to_string(sites) + " sites" : "") +
                     " needs about " + format_gib(double(need)) + " for " +
                     (plan.format.raster ? std::string("the labeller's tree and the raster's strips")
                                         : std::string("its outline cells and the labeller's tiles")) +
                     ", more than the " + format_gib(double(allowed)) + " allowed" +
                     (memory_limit_bytes ? "" : " (80% of this host's " + format_gib(double(ram)) + " of RAM)") +
                     ": choose a lower -level");
}

RunPlan plan_run(const std::string& destination, const VoronoiOptions& options) {
  RunPlan plan = plan_level(options);
  if (options.tile_count > 0) throw VoronoiError("-tile: a tile job is planned by plan_tile_job");
  if (options.part) throw VoronoiError("-part: a part is what a tile job writes: give -tile K/N");
  plan.format = choose_output_format(destination, options.format, options.kind);
  if (!plan.format.raster && !options.raster.bands.empty()) {
    throw VoronoiError("-bands is for raster output; " + plan.format.driver + " output is vector: use -layers");
  }
  if (!options.merge.empty()) {
    if (plan.format.raster) {
      throw VoronoiError("-merge joins tile products into vector output; " + plan.format.driver +
                         " output is a raster, which a whole run writes (strip by strip, in bounded memory)");
    }
    plan.merge_files = tile_product_files(options.merge);
  }
  static_cast<write::VectorLayers&>(plan.vector) = options.vector;
  plan.vector.driver = plan.format.driver;
  if (plan.format.raster) {
    plan_raster(plan, options);
  } else {
    refuse_raster_options(plan, options);
    check_vector_destination(destination, plan);
  }

  if (plan.format.raster) {
    plan_raster_labels(plan, options);
  } else {
    plan_labeller(plan, options, plan.cells_layer);
  }
  check_run_memory(plan, options.memory_limit_bytes, 0);
  check_destination_space(destination, plan, options);
  plan.read_end = kReadEnd;  // the label stage's end is set with the devices (settle_devices)
  return plan;
}

namespace {

// A raster part's rows (pixels, from the top) of the whole raster: for the lon/lat grid, rows
// [floor((K-1) H / N), floor(K H / N)) of its H; for the QTM-coded raster, the rows of the tile's
// cells (grid::tile_range: whole octant rows, each one pixel row), as the vector parts' tiles.
void plan_raster_part_rows(RunPlan& plan, const VoronoiOptions& options) {
  write::RasterSize size;
  try {
    size = write::raster_size(plan.level, plan.raster);
  } catch (const write::WriteError& e) {
    throw VoronoiError(e.what());
  }
  const std::int64_t k = options.tile_index, n = options.tile_count, height = size.height;
  if (plan.raster.layout == write::RasterGrid::Layout::lonlat) {
    if (n > height) {
      throw VoronoiError("-tile " + std::to_string(k) + "/" + std::to_string(n) + ": the raster has " +
                         std::to_string(height) + " rows, fewer than the " + std::to_string(n) +
                         " tiles: choose at most " + std::to_string(height) + " tiles, or more rows (-ts, -tr)");
    }
    plan.raster.first_row = static_cast<int>((k - 1) * height / n);
    plan.raster.part_rows = static_cast<int>(k * height / n) - plan.raster.first_row;
    return;
  }
  grid::CodeRange range;
  try {
    range = grid::tile_range(plan.level, options.tile_index, options.tile_count);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-tile: ") + e.what());
  }
  const auto pixel_row = [&](grid::Code code) {
    if (code == grid::cell_count(plan.level)) return height;
    const grid::Cell cell = grid::cell_of(code, plan.level);
    return static_cast<std::int64_t>(cell.octant) * static_cast<std::int64_t>(grid::rows_per_octant(plan.level)) + cell.row;
  };
  plan.raster.first_row = static_cast<int>(pixel_row(range.first));
  plan.raster.part_rows = static_cast<int>(pixel_row(range.end)) - plan.raster.first_row;
}

// A raster part's plan (-tile K/N -part with a raster destination): the whole run's raster plan
// and labels, and the part's rows; every site is read (the sites that can own a cell of a band
// of pixel rows are no range of codes), so plan.label.range stays the whole level.
void plan_raster_part(RunPlan& plan, const VoronoiOptions& options) {
  plan_raster(plan, options);
  plan_raster_labels(plan, options);
  plan_raster_part_rows(plan, options);
  plan.part = true;
}

// A part's destination (-tile K/N -part): vector output in a GeoPackage, whose metadata keeps the
// part's identity for the index (part_index.hpp); layers that can be cut at a tile's edges. (A
// raster destination is planned by plan_raster_part.)
void plan_part_destination(const std::string& destination, const VoronoiOptions& options, RunPlan& plan) {
  if (plan.format.driver != "GPKG") {
    throw VoronoiError("-part: a part is a GeoPackage (-of GPKG, or a .gpkg name), not " + plan.format.driver +
                       ": its metadata keeps the level, tile and source that the index of the parts checks");
  }
  static_cast<write::VectorLayers&>(plan.vector) = options.vector;
  plan.vector.driver = plan.format.driver;
  refuse_raster_options(plan, options);
  plan.vector.part = plan.part = true;
  if (std::find(plan.vector.layers.begin(), plan.vector.layers.end(), "voronoi_edges") != plan.vector.layers.end()) {
    throw VoronoiError("-part: a part holds no voronoi_edges layer (an edge's line and its length belong to the "
                       "whole level, not to one tile): choose from regions, boundary_cells, cells, or write the "
                       "edges with a one-file -merge");
  }
  check_vector_destination(destination, plan);
}

}  // namespace

RunPlan plan_tile_job(const std::string& destination, const VoronoiOptions& options) {
  RunPlan plan = plan_level(options);
  if (!options.merge.empty()) throw VoronoiError("-tile and -merge: a run labels one tile, or merges all of them");
  if (destination.empty()) throw VoronoiError("-tile: no file named for the tile product");
  if (options.part) plan.format = choose_output_format(destination, options.format, options.kind);
  if (options.part && plan.format.raster) {
    plan.tile_index = options.tile_index;
    plan.tile_count = options.tile_count;
    plan_raster_part(plan, options);
    check_run_memory(plan, options.memory_limit_bytes, 0);
    check_destination_space(destination, plan, options);
    plan.read_end = kReadEnd;
    return plan;
  }
  if (options.part) {
    plan_part_destination(destination, options, plan);
  } else if (!EQUAL(CPLGetExtension(destination.c_str()), kTileProductExtension + 1)) {  // ".qtmt" without its dot
    // part1.gpkg would be a tile product under a GeoPackage's name: GIS software cannot read it.
    throw VoronoiError("-tile: '" + destination + "': a tile job writes a tile product, which only -merge reads: " +
                       "name it with " + kTileProductExtension + ", and give the output's name to the -merge run");
  }
  if (!options.raster.bands.empty()) {
    // As the tool refuses every output option of a tile job; -merge writes vector output only.
    throw VoronoiError("-bands: a tile job writes a tile product, not a raster; a raster is written by a whole run, or "
                       "in parts by tile jobs with -part");
  }
  plan.tile_index = options.tile_index;
  plan.tile_count = options.tile_count;
  plan_labeller(plan, options, plan.cells_layer);  // a part's cells layer: its cells' distances
  try {
    plan.label.range = grid::tile_range(plan.level, options.tile_index, options.tile_count);
  } catch (const std::invalid_argument& e) {
    throw VoronoiError(std::string("-tile: ") + e.what());
  }
  check_run_memory(plan, options.memory_limit_bytes, 0);
  // Labelling is nearly all of a tile job (a part's write is weighed as a whole run's:
  // settle_devices).
  plan.read_end = kReadEnd;
  plan.label_end = 0.98;
  return plan;
}

void check_devices(const RunPlan& plan, int cuda_devices) {
  const DeviceSpec device = parse_device_spec(plan.label.device);
  const int missing = first_missing_device(device, cuda_devices);
  if (missing < 0) return;
  // Restricted to the devices asked for (common/visible_devices.hpp), CUDA counts only those.
  throw VoronoiError("-device " + plan.label.device + ": " +
                     (cuda_devices <= 0 ? std::string("no usable CUDA GPU found")
                      : visible_devices().restricted
                          ? "this host has no CUDA device cuda:" + std::to_string(missing)
                          : "this host has " + std::to_string(cuda_devices) + " CUDA device(s)") +
                     "; use -device cpu or auto");
}

label::AutoDevice estimate_auto_device(const RunPlan& plan, std::uint64_t sites, std::uint64_t candidates) {
  label::LabelWork work;
  work.level = plan.level;
  work.sites = sites;
  work.candidates = candidates;
  work.outlines = !plan.format.raster;
  const double cells = static_cast<double>(grid::cell_count(plan.level));
  if (plan.label.range.end != 0) work.share = static_cast<double>(plan.label.range.size()) / cells;
  if (plan.cells_layer) work.every_cell = grid::cell_count(plan.level);
  if (plan.format.raster) {
    try {
      const write::RasterSize size = write::raster_size(plan.level, plan.raster);
      const int rows = plan.raster.part_rows ? plan.raster.part_rows : size.height;  // a part's rows only
      work.every_cell = static_cast<std::uint64_t>(size.width) * static_cast<std::uint64_t>(rows);
    } catch (const write::WriteError&) {
      // bad sizes are reported by plan_run
    }
  }
  work.threads = thread_count(plan.label.threads);
  return label::choose_auto_device(work);
}

void settle_auto_device(RunPlan& plan, const label::AutoDevice& choice, int cuda_devices) {
  plan.label.device = choice.gpu && cuda_devices > 0 ? "cuda" : "cpu";
}

std::string auto_device_summary(const std::string& device, const label::AutoDevice& choice, int cuda_devices) {
  return "auto: " + device + ", " + choice.reason() + (choice.gpu && cuda_devices <= 0 ? ", but no usable CUDA GPU" : "");
}

void settle_devices(RunPlan& plan, const VoronoiOptions& options, int cuda_devices) {
  check_devices(plan, cuda_devices);
  plan.cuda_devices = cuda_devices;
  plan.label.memory_limit_bytes = tile_limit(options.memory_limit_bytes, plan.label.device, cuda_devices);
  // The writer's geodesics go where the labels are made: the first GPU of the list.
  const DeviceSpec device = parse_device_spec(plan.label.device);
  plan.vector.geodesic_device =
      labels_on_cpu(plan.label.device, cuda_devices) ? -1 : device.all ? 0 : cuda_ordinal(device.index);
  if (plan.tile_count == 0 || plan.part) set_stage_ends(plan);
}

}  // namespace qtmv::pipeline
