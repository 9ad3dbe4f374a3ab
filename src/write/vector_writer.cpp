#include "write/vector_writer.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <cpl_string.h>
#include <gdal_priv.h>

#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm.hpp"
#include "write/gpkg_rows.hpp"
#include "write/vector_dataset_writer.hpp"
#include "write/vector_layer_writers.hpp"

namespace qtmv::write {

const char* const kVectorLayerNames[4] = {"regions", "boundary_cells", "voronoi_edges", "cells"};

using grid::Code;

std::string check_layer_names(const std::vector<std::string>& layers) {
  std::string valid;
  for (const char* name : kVectorLayerNames) valid += (valid.empty() ? "" : ", ") + std::string(name);
  if (layers.empty()) return "no layer named: choose from " + valid;
  for (const std::string& name : layers) {
    if (std::find(std::begin(kVectorLayerNames), std::end(kVectorLayerNames), name) == std::end(kVectorLayerNames)) {
      return "no layer '" + name + "': choose from " + valid;
    }
  }
  return {};
}

void write_vector(const std::string& path, const label::Outlines& outlines, const CellTileSource& cell_tiles,
                  const sites::SiteTable& table, const VectorOptions& options) {
  // Everything that can be refused is refused before the destination is created.
  if (const std::string problem = check_layer_names(options.layers); !problem.empty()) {
    throw WriteError(path + ": " + problem);
  }
  std::vector<std::string> layers;
  for (const std::string& name : options.layers) {
    if (std::find(layers.begin(), layers.end(), name) == layers.end()) layers.push_back(name);
  }

  if (!grid::is_valid_level(outlines.level)) throw std::invalid_argument("write_vector: bad level " + std::to_string(outlines.level));
  const auto site_count = static_cast<std::int32_t>(table.sites.size());
  if (outlines.site_count != site_count) {
    throw std::invalid_argument("write_vector: the outlines have " + std::to_string(outlines.site_count) +
                                " sites, the table " + std::to_string(site_count));
  }
  StepTrace trace(TraceStage::write);
  label::check_outlines(outlines);
  trace("outline cells checked");
  if (options.part && std::find(layers.begin(), layers.end(), "voronoi_edges") != layers.end()) {
    throw WriteError(path + ": a part holds no voronoi_edges layer (an edge's line and length belong to the "
                     "whole level, not to one tile)");
  }
  if (!options.part && !(outlines.range == grid::whole_level(outlines.level))) {
    throw std::invalid_argument("write_vector: the outlines hold only codes " + std::to_string(outlines.range.first) +
                                " to " + std::to_string(outlines.range.end) + " of the level");
  }
  const bool want_cells = std::find(layers.begin(), layers.end(), "cells") != layers.end();
  if (want_cells && !cell_tiles) throw std::invalid_argument("write_vector: the cells layer needs the cells' labels");
  const Code cells = outlines.range.size();
  const LayerInput in{outlines, cell_tiles, table, site_count, options.all_ring_vertices(), options.geodesic_device,
                 options.messages, options.part};
  std::uint64_t boundary_count = 0;
  const auto outline_cells = static_cast<std::int64_t>(outlines.cells.size());
#pragma omp parallel for schedule(static) num_threads(thread_count(0)) reduction(+ : boundary_count)
  for (std::int64_t k = 0; k < outline_cells; ++k) boundary_count += outlines.cells[static_cast<std::size_t>(k)].boundary() ? 1 : 0;

  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(options.driver.c_str());
  if (!driver) {
    GDALAllRegister();
    driver = GetGDALDriverManager()->GetDriverByName(options.driver.c_str());
  }
  if (!driver) throw WriteError(path + ": unknown format '" + options.driver + "'");
  if (!driver->GetMetadataItem(GDAL_DCAP_VECTOR) || !driver->GetMetadataItem(GDAL_DCAP_CREATE)) {
    throw WriteError(path + ": the " + options.driver + " driver cannot create vector datasets");
  }

  // Progress shares: each layer's expected time in microseconds, from the level 11 run of
  // bench/RESULTS.md ("qtmvoronoi end to end") on 2 cores: regions trace and measure every cell, then write a
  // feature per site; boundary_cells and cells cost per row; voronoi_edges gathers over every
  // cell and writes about 3 pairs per site. In GeoPackage through OGR features (not direct rows)
  // the close builds the R-trees of regions and voronoi_edges, about 9 us per feature.
  const double cell_count = static_cast<double>(cells), sites = static_cast<double>(site_count);
  const double outline_count = static_cast<double>(outlines.cells.size());
  const bool rtrees = EQUAL(options.driver.c_str(), "GPKG") && !gpkg_direct_rows_enabled();
  std::vector<double> work;
  double close_work = 1;
  for (const std::string& name : layers) {
    if (name == "regions") work.push_back(1.5 * outline_count + 4 * sites + 1);
    if (name == "boundary_cells") work.push_back(0.4 * static_cast<double>(boundary_count) + 1);
    if (name == "voronoi_edges") work.push_back(1.0 * outline_count + 3 * 2.5 * sites + 1);
    if (name == "cells") work.push_back(0.3 * cell_count + 1);
    if (rtrees && name == "regions") close_work += 9 * sites;
    if (rtrees && name == "voronoi_edges") close_work += 9 * 3 * sites;
  }
  double total = close_work;
  for (double x : work) total += x;

  // Outlives the dataset, which is closed inside it even on a throw.
  gdal::ErrorCapture trap(gdal::ErrorCapture::Warnings::pass_on);
  VectorDatasetWriter writer(path, options, trap, total);
  writer.open(driver);
  trace("dataset created");
  // Regions written before voronoi_edges hand on the edges' lengths from their own pass.
  const auto position = [&](const char* name) { return std::find(layers.begin(), layers.end(), name) - layers.begin(); };
  const bool lengths_from_regions = position("regions") < position("voronoi_edges") &&
                                    position("voronoi_edges") < static_cast<std::ptrdiff_t>(layers.size());
  std::vector<PairLength> pair_lengths;
  for (std::size_t k = 0; k < layers.size(); ++k) {
    const std::string& name = layers[k];
    trace.restart();
    if (name == "regions") write_regions(writer, in, work[k], lengths_from_regions ? &pair_lengths : nullptr);
    if (name == "boundary_cells") write_boundary_cells(writer, in, work[k], boundary_count);
    if (name == "voronoi_edges") write_voronoi_edges(writer, in, work[k], lengths_from_regions ? &pair_lengths : nullptr);
    if (name == "cells") write_cells(writer, in, work[k]);
    trace(("layer " + name + ", all told").c_str());
  }
  trace.restart();
  writer.close();
  trace("dataset closed");
  writer.report_done();
}

void write_vector(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const VectorOptions& options) {
  if (!grid::is_valid_level(labels.level)) throw std::invalid_argument("write_vector: bad level " + std::to_string(labels.level));
  if (!labels.site) throw std::invalid_argument("write_vector: no site labels");
  const auto site_count = static_cast<std::int32_t>(table.sites.size());
  const label::Outlines outlines = label::outlines_of_dense(labels.level, labels.site, labels.boundary, site_count);
  const CellTileSource whole = [&](const std::function<void(const CellTile&)>& sink) {
    const Code cells = grid::cell_count(labels.level);
    if (labels.boundary) {
      sink({0, cells, labels.site, labels.distance_m, labels.boundary});
      return;
    }
    std::vector<std::uint8_t> flags(cells);
    for (Code code = 0; code < cells; ++code) flags[code] = is_boundary(labels, code) ? 1 : 0;
    sink({0, cells, labels.site, labels.distance_m, flags.data()});
  };
  write_vector(path, outlines, whole, table, options);
}

}  // namespace qtmv::write