#include "pipeline/part_index.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

#include "gdal/error_capture.hpp"
#include "pipeline/tile_product.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {

namespace {

namespace fs = std::filesystem;

// The metadata items of a part (their names), version 1.
constexpr const char* kPartVersion = "QTMV_PART";
constexpr const char* kLevel = "QTMV_LEVEL";
constexpr const char* kRule = "QTMV_RULE";
constexpr const char* kTile = "QTMV_TILE";
constexpr const char* kSource = "QTMV_SOURCE";
constexpr const char* kFingerprint = "QTMV_SOURCE_FINGERPRINT";
constexpr const char* kLayers = "QTMV_LAYERS";

std::string rule_name(label::Rule rule) { return rule == label::Rule::exact ? "exact" : "cell"; }

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ",") + item;
  return out;
}

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(d); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

/// One part as its metadata and layers say: opened, checked for what makes it a part, closed.
struct PartFile {
  std::string path;
  PartIdentity identity;
  /// Per layer of identity.layers: rows, geometry type, the fields' names.
  std::vector<std::uint64_t> rows;
  std::vector<OGRwkbGeometryType> types;
  std::vector<std::string> fields;

  VoronoiError fail(const std::string& why) const { return VoronoiError("-merge: '" + path + "': " + why); }
};

PartFile read_part(const std::string& path) {
  PartFile part;
  part.path = path;
  gdal::ErrorCapture errors;
  const char* const drivers[] = {"GPKG", nullptr};
  const DatasetPtr dataset(static_cast<GDALDataset*>(
      GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers, nullptr, nullptr)));
  const std::string not_a_part = "not a part (a GeoPackage that qtmvoronoi -tile K/N -part wrote)";
  if (!dataset) throw part.fail(not_a_part);
  const auto item = [&](const char* name) {
    const char* value = dataset->GetMetadataItem(name);
    if (!value) throw part.fail(std::string(not_a_part) + ": no metadata item " + name);
    return std::string(value);
  };
  if (item(kPartVersion) != "1") {
    throw part.fail("a part of version " + item(kPartVersion) + "; this qtmvoronoi reads version 1: run the tile " +
                    "jobs again with this version");
  }
  PartIdentity& id = part.identity;
  const std::string rule = item(kRule);
  const std::string tile = item(kTile);
  unsigned long long fingerprint = 0;
  if (std::sscanf(item(kLevel).c_str(), "%d", &id.level) != 1 || (rule != "exact" && rule != "cell") ||
      std::sscanf(tile.c_str(), "%d/%d", &id.index, &id.count) != 2 || id.index < 1 || id.index > id.count ||
      std::sscanf(item(kFingerprint).c_str(), "%llx", &fingerprint) != 1) {
    throw part.fail("corrupt part (its metadata holds impossible values)");
  }
  id.rule = rule == "exact" ? label::Rule::exact : label::Rule::cell;
  id.source = item(kSource);
  id.source_fingerprint = fingerprint;
  const CPLStringList layers(CSLTokenizeString2(item(kLayers).c_str(), ",", 0));
  for (int k = 0; k < layers.size(); ++k) id.layers.emplace_back(layers[k]);
  if (id.layers.empty()) throw part.fail("corrupt part (its metadata names no layer)");
  for (const std::string& name : id.layers) {
    OGRLayer* layer = dataset->GetLayerByName(name.c_str());
    if (!layer) throw part.fail("no layer '" + name + "', which its metadata names");
    const GIntBig count = layer->GetFeatureCount(TRUE);
    if (count < 0) throw part.fail("cannot count the rows of layer '" + name + "'");
    part.rows.push_back(static_cast<std::uint64_t>(count));
    part.types.push_back(layer->GetGeomType());
    std::string fields;
    const OGRFeatureDefn* defn = layer->GetLayerDefn();
    for (int f = 0; f < defn->GetFieldCount(); ++f) {
      fields += std::string(f ? "," : "") + defn->GetFieldDefn(f)->GetNameRef() + ":" +
                OGRFieldDefn::GetFieldTypeName(defn->GetFieldDefn(f)->GetType());
    }
    part.fields.push_back(fields);
  }
  return part;
}

/// Refuses a part that does not belong with the first one (`first`).
void check_same_run(const PartFile& part, const PartFile& first) {
  const PartIdentity &a = part.identity, &b = first.identity;
  const std::string than = ", but '" + first.path + "' is ";
  if (a.level != b.level) {
    throw part.fail("a part of level " + std::to_string(a.level) + than + "of level " + std::to_string(b.level));
  }
  if (a.rule != b.rule) {
    throw part.fail("a part labelled with -distance " + rule_name(a.rule) + than + "labelled with -distance " +
                    rule_name(b.rule));
  }
  if (a.source != b.source) {
    throw part.fail("a part of '" + a.source + "'" + than + "a part of '" + b.source +
                    "': all parts come from one source read with the same options");
  }
  if (a.source_fingerprint != b.source_fingerprint) {
    throw part.fail("a part of '" + a.source + "' read with other options (-l, -where, -sql, -s_srs, -oo, -edges, " +
                    "-wrap, -strict, -makevalid), or after it changed (its size or time), than '" + first.path +
                    "': all parts come from one source read with the same options");
  }
  if (a.count != b.count) {
    throw part.fail("tile " + std::to_string(a.index) + " of " + std::to_string(a.count) + than + "a tile of " +
                    std::to_string(b.count) + ": all parts come from one split -tile K/N");
  }
  if (a.layers != b.layers || part.fields != first.fields || part.types != first.types) {
    throw part.fail("a part with the layers " + join(a.layers) + than + "a part with the layers " + join(b.layers) +
                    (a.layers == b.layers ? " (their fields differ)" : "") +
                    ": all parts are written with the same -layers");
  }
}

/// The path of `part` as the index at `destination` names it: relative to the index's directory
/// where both are local files, else as given (absolute where it is a local file).
std::pair<std::string, bool> path_from_index(const std::string& part, const std::string& destination) {
  if (part.rfind("/vsi", 0) == 0 || destination.rfind("/vsi", 0) == 0) return {part, false};
  std::error_code error;
  const fs::path part_path = fs::absolute(part, error);
  const fs::path index_dir = fs::absolute(destination, error).parent_path();
  if (error) return {part, false};
  const fs::path relative = part_path.lexically_normal().lexically_relative(index_dir.lexically_normal());
  if (relative.empty()) return {part_path.lexically_normal().string(), false};
  return {relative.string(), true};
}

std::string xml(const std::string& text) {
  char* escaped = CPLEscapeString(text.c_str(), -1, CPLES_XML);
  std::string out = escaped;
  CPLFree(escaped);
  return out;
}

std::string geometry_type_name(OGRwkbGeometryType type) {
  switch (wkbFlatten(type)) {
    case wkbPolygon: return "wkbPolygon";
    case wkbMultiPolygon: return "wkbMultiPolygon";
    case wkbMultiLineString: return "wkbMultiLineString";
    default: return "wkbUnknown";
  }
}

/// The index's XML: a union layer per layer over the parts in tile order.
std::string index_xml(const std::map<int, PartFile>& parts, const std::string& destination,
                      PartIndexSummary& summary) {
  const PartFile& first = parts.begin()->second;
  std::string out = "<OGRVRTDataSource>\n";
  for (std::size_t l = 0; l < first.identity.layers.size(); ++l) {
    const std::string& name = first.identity.layers[l];
    std::uint64_t rows = 0;
    out += "  <OGRVRTUnionLayer name=\"" + xml(name) + "\">\n";
    for (const auto& [index, part] : parts) {
      const auto [path, relative] = path_from_index(part.path, destination);
      out += "    <OGRVRTLayer name=\"" + xml(name) + "_" + std::to_string(index) + "\">\n";
      out += "      <SrcDataSource relativeToVRT=\"" + std::string(relative ? "1" : "0") + "\" shared=\"1\">" + xml(path) +
             "</SrcDataSource>\n";
      out += "      <SrcLayer>" + xml(name) + "</SrcLayer>\n";
      out += "    </OGRVRTLayer>\n";
      rows += part.rows[l];
    }
    out += "    <FieldStrategy>FirstLayer</FieldStrategy>\n";
    out += "    <GeometryType>" + geometry_type_name(first.types[l]) + "</GeometryType>\n";
    out += "    <LayerSRS>EPSG:4326</LayerSRS>\n";
    out += "    <FeatureCount>" + std::to_string(rows) + "</FeatureCount>\n";
    out += "  </OGRVRTUnionLayer>\n";
    summary.layers.emplace_back(name, rows);
  }
  out += "</OGRVRTDataSource>\n";
  return out;
}

}  // namespace

std::uint64_t source_fingerprint(const std::string& source, const sites::SourceOptions& options) {
  // FNV-1a over the fields, each ended by a zero byte: the same bytes on every host.
  std::uint64_t h = 0xcbf29ce484222325ull;
  const auto add = [&](const std::string& text) {
    for (const char c : text) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ull;
    h = h * 0x100000001b3ull;
  };
  add(source);
  VSIStatBufL stat;
  if (VSIStatL(source.c_str(), &stat) == 0 && !VSI_ISDIR(stat.st_mode)) {
    add(std::to_string(stat.st_size));
    add(std::to_string(static_cast<long long>(stat.st_mtime)));
  }
  add(std::to_string(options.layers.size()));
  for (const std::string& layer : options.layers) add(layer);
  add(options.where);
  add(options.sql);
  add(options.dialect);
  add(options.source_srs);
  add(std::to_string(options.open_options.size()));
  for (const std::string& option : options.open_options) add(option);
  add(options.edges == sites::EdgeShape::lonlat ? "lonlat" : "geodesic");
  add(options.wrap == sites::WrapMode::automatic ? "auto" : "none");
  add(options.strict ? "strict" : "");
  add(options.make_valid ? "makevalid" : "");
  return h;
}

std::vector<std::pair<std::string, std::string>> part_metadata(const PartIdentity& part) {
  char fingerprint[24];
  std::snprintf(fingerprint, sizeof fingerprint, "%016" PRIx64, part.source_fingerprint);
  return {{kPartVersion, "1"},
          {kLevel, std::to_string(part.level)},
          {kRule, rule_name(part.rule)},
          {kTile, std::to_string(part.index) + "/" + std::to_string(part.count)},
          {kSource, part.source},
          {kFingerprint, fingerprint},
          {kLayers, join(part.layers)}};
}

bool writes_part_index(const std::string& destination, const VoronoiOptions& options) {
  if (options.merge.empty()) return false;
  if (!options.format.empty()) return EQUAL(options.format.c_str(), "VRT");
  return EQUAL(CPLGetExtension(destination.c_str()), "vrt");
}

std::vector<std::string> part_files(const std::vector<std::string>& paths) {
  return merge_input_files(paths, ".gpkg",
                           "a directory without parts (.gpkg files that -tile K/N -part wrote); tile products "
                           "(.qtmt) are joined by a -merge into one file, not indexed");
}

PartIndexSummary write_part_index(const std::vector<std::string>& files, const std::string& path,
                                  const std::string& destination) {
  if (files.empty()) throw VoronoiError("-merge: no parts given");
  std::map<int, PartFile> parts;  // by tile
  const PartFile* first = nullptr;
  for (const std::string& file : files) {
    PartFile part = read_part(file);
    if (first) check_same_run(part, *first);
    const int index = part.identity.index;
    if (const auto same = parts.find(index); same != parts.end()) {
      throw part.fail("tile " + std::to_string(index) + "/" + std::to_string(part.identity.count) + " again; '" +
                      same->second.path + "' is that tile too");
    }
    const PartFile& placed = parts.emplace(index, std::move(part)).first->second;
    if (!first) first = &placed;
  }
  const int count = first->identity.count;
  if (static_cast<int>(parts.size()) != count) {
    const MissingTiles missing = missing_tiles(count, [&](int k) { return parts.count(k) > 0; });
    throw VoronoiError("-merge: " + std::to_string(missing.count) + " of the " + std::to_string(count) +
                       " parts missing (tile " + missing.list + ")");
  }
  PartIndexSummary summary;
  summary.parts = count;
  summary.level = first->identity.level;
  const std::string text = index_xml(parts, destination, summary);
  gdal::ErrorCapture errors;
  VSILFILE* file = VSIFOpenL(path.c_str(), "wb");
  if (!file) {
    const std::string said = errors.take();
    throw VoronoiError("'" + destination + "': cannot create the index" + (said.empty() ? "" : " (GDAL: " + said + ")"));
  }
  bool ok = VSIFWriteL(text.data(), 1, text.size(), file) == text.size();
  ok = VSIFCloseL(file) == 0 && ok;
  if (!ok) throw VoronoiError("'" + destination + "': writing the index failed (disk full?)");
  return summary;
}

}  // namespace qtmv::pipeline
