// The boundary_cells layer (vector_writer.hpp): one Polygon per boundary cell, from the outline
// cells.
#include <cstdint>
#include <vector>

#include <ogrsf_frmts.h>

#include "write/vector_layer_writers.hpp"

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
  std::uint64_t done = 0;
  for (const label::OutlineCell& cell : in.outlines.cells) {
    if (!cell.boundary) continue;
    const auto site = static_cast<std::size_t>(cell.site);
    const RowValue values[] = {RowValue::of(static_cast<std::int64_t>(cell.code)), fid_value(in.table.sites[site].fid),
                               in.composite() ? in.layer_of(site) : RowValue{}};
    rows.add(cell.code, level, values);
    if (++done % kProgressEvery == 0) w.layer_progress(static_cast<double>(done), static_cast<double>(count));
  }
  rows.finish();
  w.end_layer();
}

}  // namespace qtmv::write
