// The boundary_cells layer (vector_writer.hpp): one Polygon per boundary cell, from the outline
// cells.
#include <cstdint>
#include <vector>

#include <ogrsf_frmts.h>

#include "write/vector_layer_writers.hpp"
#include "write/work_ahead.hpp"

namespace qtmv::write {

void write_boundary_cells(VectorDatasetWriter& w, const LayerInput& in, double work, std::uint64_t count) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("boundary_cells", wkbPolygon, work, /*per_cell=*/true);
  OGRFieldDefn code_field("code", OFTInteger64);
  OGRFieldDefn fid_field("site_fid", OFTInteger64);
  std::vector<int> fields{w.add_field(code_field), w.add_field(fid_field)};
  if (in.composite()) {
    OGRFieldDefn layer_field("site_layer", OFTString);
    fields.push_back(w.add_field(layer_field));
  }
  w.begin_features();
  CellRows rows(w, layer, fields);
  // Blocks of outline cells, the boundary cells' polygons made on the helper's team (and this
  // thread when it waits) while this one writes the block before.
  const label::OutlineCells& cells = in.outlines.cells;
  const auto begin = [&](std::size_t first, std::size_t last) {
    std::vector<grid::Code> codes;
    for (std::size_t k = first; k < last; ++k) {
      if (cells[k].boundary()) codes.push_back(cells[k].code());
    }
    const std::size_t pieces = codes.size();
    return std::make_pair(rows.begin(std::move(codes), level), pieces);
  };
  const auto make = [&](CellPolygons& block, std::size_t k) { rows.make(block, k); };
  std::uint64_t done = 0;
  const auto write = [&](std::size_t first, std::size_t last, const CellPolygons& block) {
    std::size_t row = 0;
    for (std::size_t k = first; k < last; ++k) {
      const label::OutlineCell& cell = cells[k];
      if (!cell.boundary()) continue;
      const auto site = static_cast<std::size_t>(cell.site);
      const RowValue values[] = {RowValue::of(static_cast<std::int64_t>(cell.code())), fid_value(in.table.sites[site].fid),
                                 in.composite() ? in.layer_of(site) : RowValue{}};
      rows.add(block, row++, values);
      if (++done % kProgressEvery == 0) w.layer_progress(static_cast<double>(done), static_cast<double>(count));
    }
    rows.end_block();
  };
  work_ahead(cells.size(), kCellBlock, kCellGrain, begin, make, write);
  rows.finish();
  w.end_layer();
}

}  // namespace qtmv::write
