// The cells layer (vector_writer.hpp): every cell of the level as a Polygon, from the cells'
// labels tile by tile.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <ogrsf_frmts.h>

#include "write/vector_layer_writers.hpp"
#include "write/work_ahead.hpp"

namespace qtmv::write {

using grid::Code;

void write_cells(VectorDatasetWriter& w, const LayerInput& in, double work) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("cells", wkbPolygon, work, /*per_cell=*/true);
  OGRFieldDefn code_field("code", OFTInteger64);
  OGRFieldDefn fid_field("site_fid", OFTInteger64);
  OGRFieldDefn distance_field("distance_m", OFTReal);
  OGRFieldDefn boundary_field("boundary", OFTInteger);
  boundary_field.SetSubType(OFSTBoolean);
  std::vector<int> fields{w.add_field(code_field), w.add_field(fid_field), w.add_field(distance_field),
                          w.add_field(boundary_field)};
  if (in.composite()) {
    OGRFieldDefn layer_field("site_layer", OFTString);
    fields.push_back(w.add_field(layer_field));
  }
  w.begin_features();
  CellRows rows(w, layer, fields);
  // The level's cells, or a part's range of them (VectorOptions::part).
  const Code first = in.outlines.range.first, end = in.outlines.range.end;
  const Code cells = end - first;
  Code next = first;
  in.cell_tiles([&](const CellTile& tile) {
    if (tile.first != next) throw std::logic_error("write_vector: the cells layer's tiles are not in code order");
    // Blocks of the tile's cells, their polygons made on the helper's team (and this thread
    // when it waits) while this one writes the block before.
    const auto begin = [&](std::size_t first, std::size_t last) {
      std::vector<Code> codes(last - first);
      for (std::size_t k = first; k < last; ++k) codes[k - first] = tile.first + k;
      return std::make_pair(rows.begin(std::move(codes), level), last - first);
    };
    const auto make = [&](CellPolygons& block, std::size_t k) { rows.make(block, k); };
    const auto write = [&](std::size_t first, std::size_t last, const CellPolygons& block) {
      for (std::size_t k = first; k < last; ++k) {
        const Code code = tile.first + k;
        const std::int32_t site = tile.site[k];
        if (site < 0 || site >= in.site_count) {
          throw std::invalid_argument("write_vector: label " + std::to_string(site) + " of cell " + std::to_string(code) +
                                      " is not a site id (0 to " + std::to_string(in.site_count - 1) + ")");
        }
        const RowValue values[] = {
            RowValue::of(static_cast<std::int64_t>(code)),
            fid_value(in.table.sites[static_cast<std::size_t>(site)].fid),
            tile.distance_m ? RowValue::of(static_cast<double>(tile.distance_m[k])) : RowValue{},
            RowValue::of(std::int64_t{tile.boundary[k] != 0 ? 1 : 0}),
            in.composite() ? in.layer_of(static_cast<std::size_t>(site)) : RowValue{}};
        rows.add(block, k - first, values);
        if ((code + 1) % kProgressEvery == 0) w.layer_progress(static_cast<double>(code + 1 - first), static_cast<double>(cells));
      }
      rows.end_block();
    };
    work_ahead(static_cast<std::size_t>(tile.count), kCellBlock, kCellGrain, begin, make, write);
    next = tile.first + tile.count;
  });
  if (next != end) throw std::logic_error("write_vector: the cells layer's tiles end before the last cell");
  rows.finish();
  w.end_layer();
}

}  // namespace qtmv::write
