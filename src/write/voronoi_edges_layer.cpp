// The voronoi_edges layer (vector_writer.hpp): one MultiLineString per pair of neighbouring
// sites, linked, measured and encoded (a GeoPackage blob, or an OGR geometry) a block of pairs at
// a time on all cores while the block before is written.
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include <ogrsf_frmts.h>

#include "common/trace.hpp"
#include "write/pair_edges.hpp"
#include "write/vector_layer_writers.hpp"
#include "write/work_ahead.hpp"

namespace qtmv::write {

namespace {

constexpr std::size_t kEdgePairBlock = 4096;  // voronoi_edges pairs measured at once

/// A pair's lines linked and measured ahead of writing: their GeoPackage blob for direct rows,
/// else their OGR geometry.
struct MeasuredPair {
  double length_m = 0;
  GpkgGeometry geometry;
  std::unique_ptr<OGRMultiLineString> feature;
};

/// A block of pairs, from its first.
struct MeasuredPairs {
  std::size_t first;
  std::vector<MeasuredPair> pairs;
};

OGRMultiLineString* make_multilinestring(const PairLines& lines) {
  auto* multi = new OGRMultiLineString;
  for (const auto& line : lines.lines) {
    auto* ls = new OGRLineString;
    ls->setNumPoints(static_cast<int>(line.size()), FALSE);
    for (std::size_t k = 0; k < line.size(); ++k) ls->setPoint(static_cast<int>(k), line[k].lon, line[k].lat);
    multi->addGeometryDirectly(ls);
  }
  return multi;
}

}  // namespace

void write_voronoi_edges(VectorDatasetWriter& w, const LayerInput& in, double work,
                         const std::vector<PairLength>* measured) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("voronoi_edges", wkbMultiLineString, work);
  OGRFieldDefn a_field("site_a", OFTInteger64);
  OGRFieldDefn b_field("site_b", OFTInteger64);
  OGRFieldDefn length_field("length_m", OFTReal);
  const int a_index = w.add_field(a_field);
  const int b_index = w.add_field(b_field);
  const int length_index = w.add_field(length_field);
  int layer_a_index = -1, layer_b_index = -1;
  if (in.composite()) {
    OGRFieldDefn layer_a("layer_a", OFTString), layer_b("layer_b", OFTString);
    layer_a_index = w.add_field(layer_a);
    layer_b_index = w.add_field(layer_b);
  }

  StepTrace trace(TraceStage::write);
  const DefaultInitVector<EdgeRef> edges = gather_edges(in.outlines);
  trace("edges gathered");
  trace_printf(TraceStage::write, "%zu cell edges between sites, %.2f per outline cell", edges.size(),
               static_cast<double>(edges.size()) / std::max<double>(1, static_cast<double>(in.outlines.cells.size())));
  std::vector<std::size_t> pair_start;  // where each pair's run of edges begins
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (k == 0 || edges[k].key != edges[k - 1].key) pair_start.push_back(k);
  }
  const std::size_t pairs = pair_start.size();
  pair_start.push_back(edges.size());
  w.layer_progress(0.2, 1.0);

  w.begin_features();
  std::vector<int> row_fields{a_index, b_index, length_index};
  if (in.composite()) row_fields.insert(row_fields.end(), {layer_a_index, layer_b_index});
  const std::unique_ptr<GpkgRows> direct = w.direct_rows(row_fields);
  FeaturePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
  const auto begin = [&](std::size_t first, std::size_t last) {
    return std::make_pair(MeasuredPairs{first, std::vector<MeasuredPair>(last - first)}, last - first);
  };
  const auto measure = [&](MeasuredPairs& block, std::size_t k) {
    const std::size_t p = block.first + k;
    MeasuredPair& out = block.pairs[k];
    const std::uint64_t key = edges[pair_start[p]].key;
    std::uint64_t units = 0;  // a pair whose edges are all on the cut is not in `measured`
    if (measured) {
      const auto it = std::lower_bound(measured->begin(), measured->end(), key,
                                       [](const PairLength& m, std::uint64_t k) { return m.key < k; });
      if (it != measured->end() && it->key == key) units = it->units;
    }
    const PairLines lines = link_pair(edges.data() + pair_start[p], edges.data() + pair_start[p + 1], level,
                                      measured ? &units : nullptr);
    out.length_m = lines.length_m;
    if (direct) {
      out.geometry.begin(GpkgGeometry::kMultiLineString, static_cast<std::uint32_t>(lines.lines.size()));
      for (const auto& line : lines.lines) out.geometry.line(line.data(), line.size());
      out.geometry.end();
    } else {
      out.feature.reset(make_multilinestring(lines));
    }
  };
  const auto write = [&](std::size_t first, std::size_t last, MeasuredPairs& block) {
    for (std::size_t p = first; p < last; ++p) {
      MeasuredPair& pair = block.pairs[p - first];
      const std::uint64_t key = edges[pair_start[p]].key;
      const auto a = static_cast<std::size_t>(key >> 32), b = static_cast<std::size_t>(key & 0xffffffffu);
      // In the order of row_fields (layer_a, layer_b only for composite sites).
      const RowValue values[] = {fid_value(in.table.sites[a].fid), fid_value(in.table.sites[b].fid),
                                 RowValue::of(pair.length_m), in.composite() ? in.layer_of(a) : RowValue{},
                                 in.composite() ? in.layer_of(b) : RowValue{}};
      if (direct) {
        w.write(*direct, pair.geometry.blob(), values);
        continue;
      }
      feature->SetGeometryDirectly(pair.feature.release());
      for (std::size_t k = 0; k < row_fields.size(); ++k) set_value(*feature, row_fields[k], values[k]);
      w.write(*feature);
    }
    if (direct) w.guard([&] { direct->flush(); });  // before the block's blobs go
    w.layer_progress(0.2 + 0.8 * static_cast<double>(last) / static_cast<double>(pairs), 1.0);
  };
  work_ahead(pairs, kEdgePairBlock, 16, begin, measure, write);
  trace("edges linked and written");
  if (direct) {
    w.guard([&] { direct->finish(); });
    trace("edges' R-tree filled");
  }
  w.end_layer();
  trace("edges layer ended");
}

}  // namespace qtmv::write
