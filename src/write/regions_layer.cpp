// The regions layer (vector_writer.hpp): one MultiPolygon per site, traced and encoded (a
// GeoPackage blob, or an OGR geometry) a block at a time on all cores while the block before is
// written.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <ogrsf_frmts.h>

#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "common/visible_devices.hpp"
#include "sites/fid_list.hpp"
#include "write/region_tracer.hpp"
#include "write/sqlite_write_behind.hpp"
#include "write/vector_layer_writers.hpp"
#include "write/work_ahead.hpp"

namespace qtmv::write {

namespace {

constexpr std::size_t kRegionBlock = 2048;  // regions traced at once

OGRLinearRing* make_ring(const LonLat* points, std::size_t n) {
  auto* ring = new OGRLinearRing;
  ring->setNumPoints(static_cast<int>(n + 1), FALSE);
  for (std::size_t k = 0; k < n; ++k) ring->setPoint(static_cast<int>(k), points[k].lon, points[k].lat);
  ring->setPoint(static_cast<int>(n), points[0].lon, points[0].lat);
  return ring;
}

OGRMultiPolygon* make_multipolygon(const Region& region) {
  auto* multi = new OGRMultiPolygon;
  for (const RegionPolygon& part : region) {
    auto* polygon = new OGRPolygon;
    polygon->addRingDirectly(make_ring(part.shell.data(), part.shell.size()));
    for (const auto& hole : part.holes) polygon->addRingDirectly(make_ring(hole.data(), hole.size()));
    multi->addGeometryDirectly(polygon);
  }
  return multi;
}

/// A region as the GeoPackage blob of its MultiPolygon (what make_multipolygon gives OGR).
void region_geometry(const Region& region, GpkgGeometry& out) {
  out.begin(GpkgGeometry::kMultiPolygon, static_cast<std::uint32_t>(region.size()));
  for (const RegionPolygon& part : region) {
    out.polygon(static_cast<std::uint32_t>(1 + part.holes.size()));
    out.ring(part.shell.data(), part.shell.size());
    for (const auto& hole : part.holes) out.ring(hole.data(), hole.size());
  }
  out.end();
}

/// A name for one of our fields that no source field has (compared without case).
std::string unique_field_name(const std::string& name, const OGRFeatureDefn* source) {
  const auto taken = [&](const std::string& candidate) { return source && source->GetFieldIndex(candidate.c_str()) >= 0; };
  if (!taken(name)) return name;
  std::string candidate = "qtmv_" + name;
  for (int k = 2; taken(candidate); ++k) candidate = "qtmv_" + name + "_" + std::to_string(k);
  return candidate;
}

/// A field's type as a message names it: "Integer", "Integer(Boolean)".
std::string type_name(const OGRFieldDefn& f) {
  std::string name = OGRFieldDefn::GetFieldTypeName(f.GetType());
  if (f.GetSubType() != OFSTNone) name += std::string("(") + OGRFieldDefn::GetFieldSubTypeName(f.GetSubType()) + ")";
  return name;
}

/// Whether some value of field `sf` of layer `layer`'s sites (Integer64) is too large for a
/// double to hold exactly (beyond 2^53).
bool beyond_double(const sites::SiteTable& table, std::size_t layer, int sf) {
  constexpr std::int64_t kExact = std::int64_t{1} << 53;
  for (const sites::SiteRecord& site : table.sites) {
    if (site.layer != layer || !site.attributes || !site.attributes->IsFieldSetAndNotNull(sf)) continue;
    const std::int64_t v = site.attributes->GetFieldAsInteger64(sf);
    if (v > kExact || v < -kExact) return true;
  }
  return false;
}

/// Widens union field `into` (of the layers before) to hold the values of `other` too (a field
/// of the same name in another layer): the same type keeps it (a subtype only when both have
/// it; the larger width, none when either has none), Integer and Integer64 make Integer64, an
/// integer and Real make Real (unless an Integer64 value is beyond a double's 2^53: String),
/// any other pair String, as ogr2ogr's merging does. `big_integers`: whether `other`'s or
/// `into`'s Integer64 values go beyond 2^53. Returns whether the type or subtype changed.
bool widen_field(OGRFieldDefn& into, const OGRFieldDefn& other, bool big_integers) {
  const OGRFieldType a = into.GetType(), b = other.GetType();
  const OGRFieldType before = a;
  const OGRFieldSubType sub_before = into.GetSubType();
  const auto is_integer = [](OGRFieldType t) { return t == OFTInteger || t == OFTInteger64; };
  OGRFieldType type = OFTString;
  if (a == b) {
    type = a;
  } else if (is_integer(a) && is_integer(b)) {
    type = OFTInteger64;
  } else if ((is_integer(a) || a == OFTReal) && (is_integer(b) || b == OFTReal) && !big_integers) {
    type = OFTReal;
  }
  if (type != a) {
    // Another type: its widths are not this one's (a number's width is no string's).
    into.SetType(type);
    into.SetSubType(OFSTNone);
    into.SetWidth(0);
    into.SetPrecision(0);
  } else {
    if (into.GetSubType() != other.GetSubType()) into.SetSubType(OFSTNone);
    if (into.GetWidth() > 0) into.SetWidth(other.GetWidth() > 0 ? std::max(into.GetWidth(), other.GetWidth()) : 0);
    into.SetPrecision(std::max(into.GetPrecision(), other.GetPrecision()));
  }
  return into.GetType() != before || into.GetSubType() != sub_before;
}

/// A Real as text that reads back as the same double: the shortest of 15 to 17 significant
/// digits that does (OGR's own conversion keeps 16, or 15, and loses the last bits).
std::string real_text(double v) {
  char text[40];
  for (int digits = 15; digits <= 17; ++digits) {
    CPLsnprintf(text, sizeof text, "%.*g", digits, v);
    if (CPLStrtod(text, nullptr) == v) break;
  }
  return text;
}

/// Whether the sources' values can go into direct GeoPackage rows exactly as OGR would write
/// them: every field of `fields` (the union) Integer, Integer64, Real or String without a subtype
/// (OGR clamps Boolean and Int16 values, rounds Float32 ones) or a default value (which an unset
/// field would take), of the same type in every layer that has it (`source_index[k][u]`: layer
/// k's field for union field u, or -1), and every string valid UTF-8 within its field's width
/// (GDAL warns and mends such values).
bool plain_source_values(const LayerInput& in, const OGRFeatureDefn& fields, const std::vector<std::vector<int>>& source_index) {
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    const OGRFieldDefn* f = fields.GetFieldDefn(u);
    const OGRFieldType type = f->GetType();
    if ((type != OFTInteger && type != OFTInteger64 && type != OFTReal && type != OFTString) ||
        f->GetSubType() != OFSTNone || f->GetDefault() != nullptr) {
      return false;
    }
    for (std::size_t k = 0; k < in.table.source_count(); ++k) {
      const int sf = source_index[k][static_cast<std::size_t>(u)];
      if (sf < 0) continue;
      const OGRFieldDefn* own = in.table.definition(k)->GetFieldDefn(sf);
      // An Integer into an Integer64 union field: the same INTEGER column, the same values.
      const bool same = own->GetType() == type || (own->GetType() == OFTInteger && type == OFTInteger64);
      if (!same || own->GetSubType() != OFSTNone) return false;
    }
  }
  // The strings' checks on all cores: a million sites' features, each a cache miss or two, took
  // 0.4 s of the writer's one thread before the first row (a CSV's fields are all strings).
  std::vector<std::pair<int, int>> string_fields;  // (union field, its width)
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    const OGRFieldDefn* f = fields.GetFieldDefn(u);
    if (f->GetType() == OFTString) string_fields.emplace_back(u, f->GetWidth());
  }
  if (string_fields.empty()) return true;
  const auto site_total = static_cast<std::int64_t>(in.table.sites.size());
  bool plain = true;
#pragma omp parallel for schedule(static) num_threads(thread_count(0)) reduction(&& : plain) if (site_total >= 4096)
  for (std::int64_t k = 0; k < site_total; ++k) {
    const sites::SiteRecord& site = in.table.sites[static_cast<std::size_t>(k)];
    if (!plain || !site.attributes) continue;
    for (const auto& [u, width] : string_fields) {
      const int sf = source_index[site.layer][static_cast<std::size_t>(u)];
      if (sf < 0 || !site.attributes->IsFieldSetAndNotNull(sf)) continue;
      const char* text = site.attributes->GetRawFieldRef(sf)->String;
      if (!CPLIsUTF8(text, -1) || (width > 0 && CPLStrlenUTF8(text) > width)) plain = false;
    }
  }
  return plain;
}

/// Field `sf` of a site's source feature as a row value (plain_source_values' types only).
RowValue source_value(const OGRFeature* feature, int sf) {
  if (sf < 0 || !feature || !feature->IsFieldSetAndNotNull(sf)) return {};
  switch (feature->GetFieldDefnRef(sf)->GetType()) {
    case OFTInteger:
    case OFTInteger64: return RowValue::of(static_cast<std::int64_t>(feature->GetFieldAsInteger64(sf)));
    case OFTReal: return RowValue::of(feature->GetFieldAsDouble(sf));
    default: return {RowValue::Kind::text, 0, 0, feature->GetRawFieldRef(sf)->String};
  }
}

/// A block of regions traced ahead of writing: their GeoPackage blobs and rows' values for direct
/// rows, or their OGR geometries (null for an empty region) for OGR features.
struct TracedRegions {
  std::size_t first = 0;  // the block's first site
  std::vector<GpkgGeometry> geometries;
  std::vector<RowValue> values;  // direct rows: each row's, one after another
  std::vector<std::unique_ptr<OGRMultiPolygon>> features;
};

/// The regions layer's fields as made: the source's, then ours.
struct RegionFields {
  // The source's fields first, as ogr2ogr would copy them; of several source layers (composite
  // sites), the union of their fields by name (of a type that holds each layer's values:
  // widen_field), and then site_layer, the layer of each site.
  OGRFeatureDefn union_fields{"fields"};
  // Per source layer: its fields' places in the union (one empty map for a table without a
  // source), and the other way round: the layer's field for each union field (or -1).
  std::vector<std::vector<int>> field_maps, source_index;
  std::vector<int> written;  // the layer's field for each union field
  // Per source layer: its Real fields whose union field is String (another layer's is text), as
  // (the layer's field, the regions layer's field): written as real_text, not as OGR's 16 digits.
  std::vector<std::vector<std::pair<int, int>>> reals_as_text;
  int layer_index = -1, fid_index = -1, cells_index = -1, area_index = -1;  // ours (site_layer: composite only)
};

/// A row's values in the order of the rows' fields (the union's, then site_layer, site_fid,
/// cells, area_m2): the source's for direct rows only (OGR copies them itself), then ours.
class RegionRowValues {
 public:
  RegionRowValues(const LayerInput& in, const RegionFields& fields, const std::vector<double>& areas)
      : in_(in), fields_(fields), areas_(areas) {}
  std::size_t count() const { return fields_.written.size() + (fields_.layer_index >= 0 ? 4 : 3); }
  /// Site s's values into out[0, count()); the source's only `with_source`.
  void fill(std::size_t s, bool with_source, RowValue* out) const {
    const sites::SiteRecord& site = in_.table.sites[s];
    std::size_t v = fields_.written.size();
    if (fields_.layer_index >= 0) out[v++] = in_.layer_of(s);
    out[v++] = fid_value(site.fid);
    out[v++] = RowValue::of(static_cast<std::int64_t>(in_.outlines.cells_per_site[s]));
    out[v++] = RowValue::of(areas_[s]);
    if (!with_source) return;
    const std::vector<int>& index = fields_.source_index[site.layer];
    for (std::size_t u = 0; u < fields_.written.size(); ++u) out[u] = source_value(site.attributes.get(), index[u]);
  }

 private:
  const LayerInput& in_;
  const RegionFields& fields_;
  const std::vector<double>& areas_;
};

/// Adds the fields to the regions layer just begun in `w`.
void add_region_fields(VectorDatasetWriter& w, const LayerInput& in, RegionFields& out) {
  OGRFeatureDefn& fields = out.union_fields;
  std::vector<std::vector<int>>& field_maps = out.field_maps;
  std::vector<std::vector<int>>& source_index = out.source_index;
  std::vector<int>& written = out.written;
  const std::size_t source_layers = std::max<std::size_t>(1, in.table.source_count());
  field_maps.resize(source_layers);
  source_index.resize(source_layers);
  // A name's fields of several layers (composite sites) whose types differ make a union field
  // that holds them all (widen_field), with one warning naming the layers and their types.
  std::vector<bool> widened;
  for (std::size_t k = 0; k < in.table.source_count(); ++k) {
    const OGRFeatureDefn* source = in.table.definition(k);
    for (int f = 0; source && f < source->GetFieldCount(); ++f) {
      const OGRFieldDefn* own = source->GetFieldDefn(f);
      int u = fields.GetFieldIndex(own->GetNameRef());
      if (u < 0) {
        fields.AddFieldDefn(own);
        u = fields.GetFieldCount() - 1;
        widened.push_back(false);
      } else {
        OGRFieldDefn* into = fields.GetFieldDefn(u);
        bool big = own->GetType() == OFTInteger64 && beyond_double(in.table, k, f);
        for (std::size_t j = 0; j < k && !big; ++j) {
          const int jf = in.table.definition(j)->GetFieldIndex(own->GetNameRef());
          big = jf >= 0 && in.table.definition(j)->GetFieldDefn(jf)->GetType() == OFTInteger64 &&
                beyond_double(in.table, j, jf);
        }
        const bool changed = widen_field(*into, *own, big);
        widened[static_cast<std::size_t>(u)] =
            widened[static_cast<std::size_t>(u)] || changed || own->GetType() != into->GetType() ||
            own->GetSubType() != into->GetSubType();
      }
      field_maps[k].push_back(u);
    }
  }
  for (std::size_t k = 0; k < source_layers; ++k) {
    source_index[k].assign(static_cast<std::size_t>(fields.GetFieldCount()), -1);
    for (std::size_t f = 0; f < field_maps[k].size(); ++f) source_index[k][static_cast<std::size_t>(field_maps[k][f])] = static_cast<int>(f);
  }
  out.reals_as_text.resize(source_layers);
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    if (!widened[static_cast<std::size_t>(u)]) continue;
    const OGRFieldDefn* field = fields.GetFieldDefn(u);
    std::string types;
    for (std::size_t k = 0; k < in.table.source_count(); ++k) {
      const int sf = source_index[k][static_cast<std::size_t>(u)];
      if (sf < 0) continue;
      types += (types.empty() ? "" : ", ") + type_name(*in.table.definition(k)->GetFieldDefn(sf)) + " in layer '" +
               in.table.layer(k) + "'";
    }
    qtmv::tell(in.messages, qtmv::Severity::warning,
               "field '" + std::string(field->GetNameRef()) + "': " + types + ": written as " + type_name(*field));
  }
  written.resize(static_cast<std::size_t>(fields.GetFieldCount()));
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    OGRFieldDefn copy(fields.GetFieldDefn(u));
    written[static_cast<std::size_t>(u)] = w.add_field(copy);
  }
  for (std::size_t k = 0; k < in.table.source_count(); ++k) {
    for (std::size_t f = 0; f < field_maps[k].size(); ++f) {
      const OGRFieldDefn* own = in.table.definition(k)->GetFieldDefn(static_cast<int>(f));
      if (own->GetType() == OFTReal && fields.GetFieldDefn(field_maps[k][f])->GetType() == OFTString) {
        out.reals_as_text[k].emplace_back(static_cast<int>(f), written[static_cast<std::size_t>(field_maps[k][f])]);
      }
    }
  }
  for (auto& map : field_maps) {
    for (int& u : map) u = written[static_cast<std::size_t>(u)];
  }
  if (in.composite()) {
    OGRFieldDefn layer_field(unique_field_name("site_layer", &fields).c_str(), OFTString);
    out.layer_index = w.add_field(layer_field);
  }
  const OGRFeatureDefn* source = &fields;
  OGRFieldDefn fid_field(unique_field_name("site_fid", source).c_str(), OFTInteger64);
  OGRFieldDefn cells_field(unique_field_name("cells", source).c_str(), OFTInteger64);
  OGRFieldDefn area_field(unique_field_name("area_m2", source).c_str(), OFTReal);
  area_field.SetWidth(24);  // up to 5.1e14 with decimals to spare where widths count (shapefiles)
  area_field.SetPrecision(3);
  out.fid_index = w.add_field(fid_field);
  out.cells_index = w.add_field(cells_field);
  out.area_index = w.add_field(area_field);
}

}  // namespace

void write_regions(VectorDatasetWriter& w, const LayerInput& in, double work, std::vector<PairLength>* pair_lengths) {
  OGRLayer* layer = w.begin_layer("regions", wkbMultiPolygon, work);

  RegionFields fields;
  add_region_fields(w, in, fields);

  StepTrace trace(TraceStage::write);
  const RingVertices vertices = in.all_ring_vertices ? RingVertices::all : RingVertices::corners;
  // The areas are summed in the tracer's pass over the outline cells, edge by edge.
  std::string device_problem;
  RegionAreaSums area_sums(in.site_count, pair_lengths != nullptr, in.geodesic_device, &device_problem);
  if (!device_problem.empty()) {
    qtmv::tell(in.messages, qtmv::Severity::warning,
         "the regions' geodesics are solved on the CPU instead of " + cuda_device_name(in.geodesic_device) + " (" +
             device_problem + ")");
  }
  bool gathered = false;  // RegionTracer's steps, in order: gather (and measure), bucket
  const auto tracer_step = [&](double f) {
    trace(gathered ? "regions' edges bucketed" : "regions' edges gathered, measured");
    if (!gathered) trace.note("of which solving geodesics (thread time)", area_sums.solve_seconds());
    gathered = true;
    w.layer_progress(0.4 * f, 1.0);
  };
  const RegionTracer tracer(in.outlines, vertices, tracer_step, &area_sums);
  const std::vector<double> areas = area_sums.areas(in.outlines.cells_per_site);
  if (pair_lengths) *pair_lengths = area_sums.pair_lengths();
  trace("regions' areas");

  w.begin_features();
  // Direct GeoPackage rows: the union's fields, then site_layer, site_fid, cells, area_m2.
  std::vector<int> row_fields = fields.written;
  if (fields.layer_index >= 0) row_fields.push_back(fields.layer_index);
  row_fields.insert(row_fields.end(), {fields.fid_index, fields.cells_index, fields.area_index});
  const std::unique_ptr<GpkgRows> direct =
      plain_source_values(in, fields.union_fields, fields.source_index) ? w.direct_rows(row_fields) : nullptr;

  // Blocks of regions traced (and made blobs of, with the rows' values, for direct rows) on the
  // helper's team, and on this thread when it is done writing the block before: two blocks held,
  // not every region's rings.
  const RegionRowValues row_values(in, fields, areas);
  // A row per site; a part's only for the sites with cells in its range (VectorOptions::part).
  std::vector<std::size_t> part_sites;
  if (in.part) {
    for (std::size_t s = 0; s < in.outlines.cells_per_site.size(); ++s) {
      if (in.outlines.cells_per_site[s] > 0) part_sites.push_back(s);
    }
  }
  const std::size_t row_count = in.part ? part_sites.size() : static_cast<std::size_t>(in.site_count);
  const auto site_of_row = [&](std::size_t row) { return in.part ? part_sites[row] : row; };
  const auto begin = [&](std::size_t first, std::size_t last) {
    TracedRegions block;
    block.first = first;
    if (direct) {
      block.geometries.resize(last - first);
      block.values.resize((last - first) * row_values.count());
    } else {
      block.features.resize(last - first);
    }
    return std::make_pair(std::move(block), last - first);
  };
  const auto link = [&](TracedRegions& block, std::size_t k) {
    const std::size_t s = site_of_row(block.first + k);
    const Region region = tracer.trace(static_cast<std::int32_t>(s));
    if (direct) {
      region_geometry(region, block.geometries[k]);
      row_values.fill(s, true, block.values.data() + k * row_values.count());
    } else if (!region.empty()) {
      block.features[k].reset(make_multipolygon(region));
    }
  };
  // The regions of sites without a cell (empty): as the driver can hold them (EmptyRows); the
  // rows it cannot hold are named in a warning at the end.
  const EmptyRows empty_rows = w.empty_rows();
  sites::FidList left_out;
  std::vector<RowValue> values(row_values.count());  // an OGR feature's
  double write_seconds = 0;  // this thread's, in write (for the trace)
  const auto write = [&](std::size_t first, std::size_t last, TracedRegions& block) {
    const auto start = std::chrono::steady_clock::now();
    for (std::size_t row = first; row < last; ++row) {
      if (direct) {
        w.write(*direct, block.geometries[row - first].blob(), block.values.data() + (row - first) * row_values.count());
        continue;
      }
      const std::size_t s = site_of_row(row);
      const sites::SiteRecord& site = in.table.sites[s];
      row_values.fill(s, false, values.data());
      std::unique_ptr<OGRMultiPolygon>& geometry = block.features[row - first];
      const bool empty = geometry == nullptr;
      if (empty && empty_rows == EmptyRows::left_out) {
        left_out.add(site.fid);
        continue;
      }
      FeaturePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
      const std::vector<int>& field_map = fields.field_maps[site.layer];
      if (site.attributes && !field_map.empty()) {
        if (feature->SetFieldsFrom(site.attributes.get(), field_map.data(), TRUE) != OGRERR_NONE) {
          w.fail("cannot copy the attributes of site " + std::to_string(s));
        }
        for (const auto& [sf, field] : fields.reals_as_text[site.layer]) {
          if (site.attributes->IsFieldSetAndNotNull(sf)) {
            feature->SetField(field, real_text(site.attributes->GetFieldAsDouble(sf)).c_str());
          }
        }
      }
      for (std::size_t k = fields.written.size(); k < row_fields.size(); ++k) set_value(*feature, row_fields[k], values[k]);
      // Empty for a site without cells; null where the driver keeps nulls but not empties.
      if (empty && empty_rows == EmptyRows::empty) geometry = std::make_unique<OGRMultiPolygon>();
      if (geometry) feature->SetGeometryDirectly(geometry.release());
      w.write(*feature);
    }
    if (direct) w.guard([&] { direct->flush(); });  // before the block's blobs go
    write_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    w.layer_progress(0.4 + 0.6 * static_cast<double>(last) / static_cast<double>(row_count), 1.0);
  };
  const SqliteWriteBehind::Totals behind_before = SqliteWriteBehind::totals();
  work_ahead(row_count, kRegionBlock, 1, begin, link, write);
  trace("regions traced and written");
  const SqliteWriteBehind::Totals behind = SqliteWriteBehind::totals();
  if (left_out.count() > 0) {
    w.warn(w.driver_name() + " drops rows without a geometry: the " + std::to_string(left_out.count()) +
           " site(s) without a cell (FIDs " + left_out.text() + ") are not in it");
  }
  trace.note("of which writing rows", write_seconds);
  if (behind.bytes > behind_before.bytes) {
    const std::string what = "  of which waiting for the file written behind (" +
                             std::to_string(behind.drains - behind_before.drains) + " times for all of it)";
    trace.note(what.c_str(), behind.waited_seconds - behind_before.waited_seconds);
  }
  if (direct) {
    w.guard([&] { direct->finish(); });
    trace("regions' R-tree filled");
  }
  w.end_layer();
  trace("regions layer ended");
}

}  // namespace qtmv::write
