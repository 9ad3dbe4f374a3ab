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
#include "pipeline/raster_part_index.hpp"
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
// A raster part's (instead of kLayers): its bands, the whole raster and the part's rows.
constexpr const char* kBands = "QTMV_BANDS";
constexpr const char* kRaster = "QTMV_RASTER";
constexpr const char* kRows = "QTMV_ROWS";

std::string rule_name(label::Rule rule) { return rule == label::Rule::exact ? "exact" : "cell"; }

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
  const GDALDatasetUniquePtr dataset(GDALDataset::FromHandle(
      GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers, nullptr, nullptr)));
  if (!dataset) throw part.fail("not a part (a GeoPackage or raster that qtmvoronoi -tile K/N -part wrote)");
  part.identity = parse_part_metadata(dataset->GetMetadata(), path);
  const PartIdentity& id = part.identity;
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

/// Refuses a part that does not belong with the first one (`first`): check_same_run, and the layers.
void check_same_layers(const PartFile& part, const PartFile& first) {
  const PartIdentity &a = part.identity, &b = first.identity;
  check_same_run(a, part.path, b, first.path);
  if (a.layers != b.layers || part.fields != first.fields || part.types != first.types) {
    throw part.fail("a part with the layers " + join_with_commas(a.layers) + ", but '" + first.path +
                    "' is a part with the layers " + join_with_commas(b.layers) +
                    (a.layers == b.layers ? " (their fields differ)" : "") +
                    ": all parts are written with the same -layers");
  }
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
    out += "  <OGRVRTUnionLayer name=\"" + xml_escaped(name) + "\">\n";
    for (const auto& [index, part] : parts) {
      const auto [path, relative] = path_from_index(part.path, destination);
      out += "    <OGRVRTLayer name=\"" + xml_escaped(name) + "_" + std::to_string(index) + "\">\n";
      out += "      <SrcDataSource relativeToVRT=\"" + std::string(relative ? "1" : "0") + "\" shared=\"1\">" + xml_escaped(path) +
             "</SrcDataSource>\n";
      out += "      <SrcLayer>" + xml_escaped(name) + "</SrcLayer>\n";
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
  std::vector<std::pair<std::string, std::string>> items{
      {kPartVersion, "1"},
      {kLevel, std::to_string(part.level)},
      {kRule, rule_name(part.rule)},
      {kTile, std::to_string(part.index) + "/" + std::to_string(part.count)},
      {kSource, part.source},
      {kFingerprint, fingerprint}};
  if (!part.raster) {
    items.emplace_back(kLayers, join_with_commas(part.layers));
    return items;
  }
  items.emplace_back(kBands, join_with_commas(part.layers));
  items.emplace_back(kRaster, part.layout + " " + std::to_string(part.width) + " " + std::to_string(part.height));
  items.emplace_back(kRows, std::to_string(part.first_row) + " " + std::to_string(part.end_row));
  return items;
}

PartIdentity parse_part_metadata(const char* const* items, const std::string& path) {
  const auto fail = [&](const std::string& why) { return VoronoiError("-merge: '" + path + "': " + why); };
  const std::string not_a_part = "not a part (a GeoPackage or raster that qtmvoronoi -tile K/N -part wrote)";
  // netCDF names its global attributes NC_GLOBAL#NAME.
  const auto find = [&](const char* name) -> const char* {
    const char* value = CSLFetchNameValue(const_cast<char**>(items), name);
    return value ? value : CSLFetchNameValue(const_cast<char**>(items), (std::string("NC_GLOBAL#") + name).c_str());
  };
  const auto item = [&](const char* name) {
    const char* value = find(name);
    if (!value) throw fail(not_a_part + ": no metadata item " + name);
    return std::string(value);
  };
  if (item(kPartVersion) != "1") {
    throw fail("a part of version " + item(kPartVersion) + "; this qtmvoronoi reads version 1: run the tile " +
               "jobs again with this version");
  }
  PartIdentity id;
  const std::string rule = item(kRule);
  const std::string tile = item(kTile);
  unsigned long long fingerprint = 0;
  const std::string corrupt = "corrupt part (its metadata holds impossible values)";
  if (std::sscanf(item(kLevel).c_str(), "%d", &id.level) != 1 || (rule != "exact" && rule != "cell") ||
      std::sscanf(tile.c_str(), "%d/%d", &id.index, &id.count) != 2 || id.index < 1 || id.index > id.count ||
      std::sscanf(item(kFingerprint).c_str(), "%llx", &fingerprint) != 1) {
    throw fail(corrupt);
  }
  id.rule = rule == "exact" ? label::Rule::exact : label::Rule::cell;
  id.source = item(kSource);
  id.source_fingerprint = fingerprint;
  id.raster = find(kBands) != nullptr;
  const CPLStringList layers(CSLTokenizeString2(item(id.raster ? kBands : kLayers).c_str(), ",", 0));
  for (int k = 0; k < layers.size(); ++k) id.layers.emplace_back(layers[k]);
  if (id.layers.empty()) throw fail(std::string("corrupt part (its metadata names no ") + (id.raster ? "band)" : "layer)"));
  if (id.raster) {
    char layout[16] = {0};
    if (std::sscanf(item(kRaster).c_str(), "%15s %d %d", layout, &id.width, &id.height) != 3 ||
        std::sscanf(item(kRows).c_str(), "%d %d", &id.first_row, &id.end_row) != 2 || id.width < 1 ||
        id.first_row < 0 || id.first_row >= id.end_row || id.end_row > id.height) {
      throw fail(corrupt);
    }
    id.layout = layout;
  }
  return id;
}

void check_same_run(const PartIdentity& a, const std::string& path, const PartIdentity& b,
                    const std::string& first_path) {
  const auto fail = [&](const std::string& why) { return VoronoiError("-merge: '" + path + "': " + why); };
  const std::string than = ", but '" + first_path + "' is ";
  if (a.raster != b.raster) {
    throw fail(std::string(a.raster ? "a raster part" : "a vector part") + than +
               (b.raster ? "a raster part" : "a vector part") +
               ": an index is over the parts of one output, all raster or all vector");
  }
  if (a.level != b.level) {
    throw fail("a part of level " + std::to_string(a.level) + than + "of level " + std::to_string(b.level));
  }
  if (a.rule != b.rule) {
    throw fail("a part labelled with -distance " + rule_name(a.rule) + than + "labelled with -distance " +
               rule_name(b.rule));
  }
  if (a.source != b.source) {
    throw fail("a part of '" + a.source + "'" + than + "a part of '" + b.source +
               "': all parts come from one source read with the same options");
  }
  if (a.source_fingerprint != b.source_fingerprint) {
    throw fail("a part of '" + a.source + "' read with other options (-l, -where, -sql, -s_srs, -oo, -edges, " +
               "-wrap, -strict, -makevalid), or after it changed (its size or time), than '" + first_path +
               "': all parts come from one source read with the same options");
  }
  if (a.count != b.count) {
    throw fail("tile " + std::to_string(a.index) + " of " + std::to_string(a.count) + than + "a tile of " +
               std::to_string(b.count) + ": all parts come from one split -tile K/N");
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

std::string join_with_commas(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ",") + item;
  return out;
}

std::string xml_escaped(const std::string& text) {
  char* escaped = CPLEscapeString(text.c_str(), -1, CPLES_XML);
  std::string out = escaped;
  CPLFree(escaped);
  return out;
}

void write_index_text(const std::string& path, const std::string& text, const std::string& destination) {
  gdal::ErrorCapture errors;
  VSILFILE* file = VSIFOpenL(path.c_str(), "wb");
  if (!file) {
    const std::string said = errors.take();
    throw VoronoiError("'" + destination + "': cannot create the index" + (said.empty() ? "" : " (GDAL: " + said + ")"));
  }
  bool ok = VSIFWriteL(text.data(), 1, text.size(), file) == text.size();
  ok = VSIFCloseL(file) == 0 && ok;
  if (!ok) throw VoronoiError("'" + destination + "': writing the index failed (disk full?)");
}

void place_tile(std::map<int, std::string>& tiles, int index, int count, const std::string& path) {
  if (const auto same = tiles.find(index); same != tiles.end()) {
    throw VoronoiError("-merge: '" + path + "': tile " + std::to_string(index) + "/" + std::to_string(count) +
                       " again; '" + same->second + "' is that tile too");
  }
  tiles.emplace(index, path);
}

void check_no_tile_missing(const std::map<int, std::string>& tiles, int count) {
  if (static_cast<int>(tiles.size()) == count) return;
  const MissingTiles missing = missing_tiles(count, [&](int k) { return tiles.count(k) > 0; });
  throw VoronoiError("-merge: " + std::to_string(missing.count) + " of the " + std::to_string(count) +
                     " parts missing (tile " + missing.list + ")");
}

bool writes_part_index(const std::string& destination, const VoronoiOptions& options) {
  if (options.merge.empty()) return false;
  if (!options.format.empty()) return EQUAL(options.format.c_str(), "VRT");
  return EQUAL(CPLGetExtension(destination.c_str()), "vrt");
}

std::vector<std::string> part_files(const std::vector<std::string>& paths) {
  return merge_input_files(paths, {".gpkg", ".tif", ".tiff"},
                           "a directory without parts (.gpkg or .tif files that -tile K/N -part wrote); tile "
                           "products (.qtmt) are joined by a -merge into one file, not indexed");
}

namespace {

/// Whether the part `path` is a raster part (its metadata names bands), opening it as any GDAL
/// dataset; a file that is no part is refused by the reader of vector parts.
bool is_raster_part(const std::string& path) {
  gdal::ErrorCapture errors;
  const GDALDatasetUniquePtr dataset(GDALDataset::FromHandle(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
  if (!dataset || dataset->GetRasterCount() == 0) return false;
  char** items = dataset->GetMetadata();
  return CSLFetchNameValue(items, kBands) != nullptr ||
         CSLFetchNameValue(items, (std::string("NC_GLOBAL#") + kBands).c_str()) != nullptr;
}

}  // namespace

PartIndexSummary write_part_index(const std::vector<std::string>& files, const std::string& path,
                                  const std::string& destination) {
  if (files.empty()) throw VoronoiError("-merge: no parts given");
  if (is_raster_part(files.front())) return write_raster_part_index(files, path, destination);
  std::map<int, PartFile> parts;  // by tile
  std::map<int, std::string> tiles;
  const PartFile* first = nullptr;
  for (const std::string& file : files) {
    if (first && is_raster_part(file)) {
      throw VoronoiError("-merge: '" + file + "': a raster part, but '" + first->path + "' is a vector part: an " +
                         "index is over the parts of one output, all raster or all vector");
    }
    PartFile part = read_part(file);
    if (first) check_same_layers(part, *first);
    const int index = part.identity.index;
    place_tile(tiles, index, part.identity.count, file);
    const PartFile& placed = parts.emplace(index, std::move(part)).first->second;
    if (!first) first = &placed;
  }
  const int count = first->identity.count;
  check_no_tile_missing(tiles, count);
  PartIndexSummary summary;
  summary.parts = count;
  summary.level = first->identity.level;
  write_index_text(path, index_xml(parts, destination, summary), destination);
  return summary;
}

}  // namespace qtmv::pipeline
