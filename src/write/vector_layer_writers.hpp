// The four layer writers of write_vector (vector_writer.hpp; the layers and their fields are
// described there), one file each: regions_layer.cpp, boundary_cells_layer.cpp,
// voronoi_edges_layer.cpp, cells_layer.cpp. Internal to the writer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/run_context.hpp"
#include "label/outline_cells.hpp"
#include "sites/site_table.hpp"
#include "write/cell_labels.hpp"
#include "write/gpkg_rows.hpp"
#include "write/region_measures.hpp"
#include "write/vector_dataset_writer.hpp"

namespace qtmv::write {

/// Cells whose polygons a per-cell layer (boundary_cells, cells) makes at once ahead of writing.
constexpr std::size_t kCellBlock = std::size_t{1} << 16;
/// Cells' polygons a thread takes at once from such a block.
constexpr std::size_t kCellGrain = 1024;

/// What every layer writer reads: the labelled level, the sites and the options it needs.
struct LayerInput {
  const label::Outlines& outlines;
  const CellTileSource& cell_tiles;  ///< the cells layer's labels
  const sites::SiteTable& table;
  std::int32_t site_count;
  bool all_ring_vertices;  ///< VectorOptions::all_ring_vertices()
  int geodesic_device;     ///< VectorOptions::geodesic_device
  const MessageSink& messages;
  bool part = false;  ///< VectorOptions::part: the outlines hold one range of the level

  /// Composite sites (several source layers): every layer says which layer its sites came from.
  bool composite() const { return table.source_count() > 1; }
  /// The name of the source layer of site s, as a field value.
  RowValue layer_of(std::size_t s) const { return RowValue::of(table.layer(table.sites[s].layer)); }
};

// Each writes its layer into `w` (work: the layer's share of the progress).

/// `pair_lengths` (may be null): also the voronoi_edges layer's lengths, from the same pass.
void write_regions(VectorDatasetWriter& w, const LayerInput& in, double work, std::vector<PairLength>* pair_lengths);

/// `count`: the boundary cells among the outline cells.
void write_boundary_cells(VectorDatasetWriter& w, const LayerInput& in, double work, std::uint64_t count);

/// `measured` (may be null): the pairs' lengths from the regions' pass (write_regions).
void write_voronoi_edges(VectorDatasetWriter& w, const LayerInput& in, double work,
                         const std::vector<PairLength>* measured);

void write_cells(VectorDatasetWriter& w, const LayerInput& in, double work);

}  // namespace qtmv::write
