#include "pipeline/raster_part_index.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gdal/error_capture.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {

namespace {

std::string number(double value) {
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

/// A band of a raster part as GDAL reads it.
struct PartBand {
  std::string type;         ///< GDAL's name of its data type
  std::string description;  ///< site_fid, boundary, distance_m
  std::string nodata;       ///< as written in the index; empty: none
  std::string unit;
  int block_width = 0, block_height = 0;
};

/// One raster part: its identity (metadata), grid and bands, opened and closed.
struct RasterPart {
  std::string path;
  PartIdentity identity;
  int width = 0, rows = 0;  ///< the dataset's size (pixels)
  double transform[6] = {0, 1, 0, 0, 0, 1};
  bool georeferenced = false;
  std::string srs_wkt, axis_mapping;  ///< lon/lat: EPSG:4326 and its data axes' order ("2,1")
  std::vector<std::pair<std::string, std::string>> metadata;  ///< the dataset's, less the part's own
  std::vector<PartBand> bands;

  VoronoiError fail(const std::string& why) const { return VoronoiError("-merge: '" + path + "': " + why); }
  std::string grid() const {
    return identity.layout + " raster of " + std::to_string(identity.width) + " x " + std::to_string(identity.height) +
           " pixels";
  }
};

void read_georeferencing(GDALDataset& dataset, RasterPart& part) {
  part.georeferenced = dataset.GetGeoTransform(part.transform) == CE_None;
  const OGRSpatialReference* srs = dataset.GetSpatialRef();
  if (!srs) return;
  char* wkt = nullptr;
  if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) part.srs_wkt = wkt;
  CPLFree(wkt);
  for (const int axis : srs->GetDataAxisToSRSAxisMapping()) {
    part.axis_mapping += (part.axis_mapping.empty() ? "" : ",") + std::to_string(axis);
  }
}

RasterPart read_raster_part(const std::string& path) {
  RasterPart part;
  part.path = path;
  gdal::ErrorCapture errors;
  // Opened as either kind: a vector part among raster parts is named as such (check_same_run).
  const GDALDatasetUniquePtr dataset(GDALDataset::FromHandle(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr)));
  if (!dataset) throw part.fail("not a part (a GeoPackage or raster that qtmvoronoi -tile K/N -part wrote)");
  char** items = dataset->GetMetadata();
  part.identity = parse_part_metadata(items, path);
  const PartIdentity& id = part.identity;
  if (!id.raster) return part;
  for (char** item = items; item && *item; ++item) {
    char* key = nullptr;
    const char* value = CPLParseNameValue(*item, &key);
    if (key && value && !STARTS_WITH(key, "QTMV_") && !STARTS_WITH(key, "NC_GLOBAL#QTMV_")) {
      part.metadata.emplace_back(key, value);
    }
    CPLFree(key);
  }
  part.width = dataset->GetRasterXSize();
  part.rows = dataset->GetRasterYSize();
  if (part.width != id.width || part.rows != id.end_row - id.first_row ||
      dataset->GetRasterCount() != static_cast<int>(id.layers.size())) {
    throw part.fail("corrupt part (its size or bands are not those its metadata names)");
  }
  read_georeferencing(*dataset, part);
  for (int b = 1; b <= dataset->GetRasterCount(); ++b) {
    GDALRasterBand* band = dataset->GetRasterBand(b);
    PartBand out;
    out.type = GDALGetDataTypeName(band->GetRasterDataType());
    out.description = band->GetDescription();
    int has_nodata = FALSE;
    const double nodata = band->GetNoDataValue(&has_nodata);
    if (has_nodata) out.nodata = number(nodata);
    out.unit = band->GetUnitType();
    band->GetBlockSize(&out.block_width, &out.block_height);
    part.bands.push_back(out);
  }
  return part;
}

/// Refuses a raster part that does not belong with the first one (`first`).
void check_same_raster(const RasterPart& part, const RasterPart& first) {
  check_same_run(part.identity, part.path, first.identity, first.path);
  const std::string than = ", but '" + first.path + "' is ";
  if (part.grid() != first.grid()) {
    throw part.fail("a part of a " + part.grid() + than + "a part of a " + first.grid() +
                    ": all parts are written with the same -raster, -tr or -ts");
  }
  if (part.identity.layers != first.identity.layers) {
    throw part.fail("a part with the bands " + join_with_commas(part.identity.layers) + than + "a part with the bands " +
                    join_with_commas(first.identity.layers) + ": all parts are written with the same -bands");
  }
  const PartBand &a = part.bands.front(), &b = first.bands.front();
  if (a.type != b.type || a.nodata != b.nodata) {
    throw part.fail("a part of " + a.type + " bands (nodata " + a.nodata + ")" + than + "a part of " + b.type +
                    " bands (nodata " + b.nodata + "): all parts are written with the same -ot");
  }
  if (part.georeferenced != first.georeferenced ||
      (part.georeferenced && (part.transform[1] != first.transform[1] || part.transform[5] != first.transform[5]))) {
    throw part.fail("a part of other pixels (its geotransform)" + than + "not");
  }
}

/// The index's XML: the whole raster's grid and metadata, and per band a source per part.
std::string raster_index_xml(const std::map<int, RasterPart>& parts, const std::string& destination) {
  const RasterPart& first = parts.begin()->second;
  const PartIdentity& id = first.identity;
  std::string out = "<VRTDataset rasterXSize=\"" + std::to_string(id.width) + "\" rasterYSize=\"" +
                    std::to_string(id.height) + "\">\n";
  if (!first.srs_wkt.empty()) {
    out += "  <SRS dataAxisToSRSAxisMapping=\"" + first.axis_mapping + "\">" + xml_escaped(first.srs_wkt) + "</SRS>\n";
  }
  if (first.georeferenced) {
    // Tile 1's first row is the whole raster's: its geotransform is the whole raster's.
    out += "  <GeoTransform>";
    for (int k = 0; k < 6; ++k) out += (k ? ", " : "") + number(first.transform[k]);
    out += "</GeoTransform>\n";
  }
  out += "  <Metadata>\n";
  for (const auto& [key, value] : first.metadata) {
    out += "    <MDI key=\"" + xml_escaped(key) + "\">" + xml_escaped(value) + "</MDI>\n";
  }
  out += "  </Metadata>\n";
  for (std::size_t b = 0; b < first.bands.size(); ++b) {
    const PartBand& band = first.bands[b];
    out += "  <VRTRasterBand dataType=\"" + band.type + "\" band=\"" + std::to_string(b + 1) + "\">\n";
    if (!band.description.empty()) out += "    <Description>" + xml_escaped(band.description) + "</Description>\n";
    if (!band.nodata.empty()) out += "    <NoDataValue>" + band.nodata + "</NoDataValue>\n";
    if (!band.unit.empty()) out += "    <UnitType>" + xml_escaped(band.unit) + "</UnitType>\n";
    for (const auto& [index, part] : parts) {
      const auto [path, relative] = path_from_index(part.path, destination);
      const std::string size = "xSize=\"" + std::to_string(part.width) + "\" ySize=\"" + std::to_string(part.rows) + "\"";
      out += "    <SimpleSource>\n";
      out += "      <SourceFilename relativeToVRT=\"" + std::string(relative ? "1" : "0") + "\">" + xml_escaped(path) +
             "</SourceFilename>\n";
      out += "      <SourceBand>" + std::to_string(b + 1) + "</SourceBand>\n";
      out += "      <SourceProperties RasterXSize=\"" + std::to_string(part.width) + "\" RasterYSize=\"" +
             std::to_string(part.rows) + "\" DataType=\"" + band.type + "\" BlockXSize=\"" +
             std::to_string(part.bands[b].block_width) + "\" BlockYSize=\"" + std::to_string(part.bands[b].block_height) +
             "\" />\n";
      out += "      <SrcRect xOff=\"0\" yOff=\"0\" " + size + " />\n";
      out += "      <DstRect xOff=\"0\" yOff=\"" + std::to_string(part.identity.first_row) + "\" " + size + " />\n";
      out += "    </SimpleSource>\n";
    }
    out += "  </VRTRasterBand>\n";
  }
  out += "</VRTDataset>\n";
  return out;
}

}  // namespace

PartIndexSummary write_raster_part_index(const std::vector<std::string>& files, const std::string& path,
                                         const std::string& destination) {
  if (files.empty()) throw VoronoiError("-merge: no parts given");
  std::map<int, RasterPart> parts;  // by tile
  std::map<int, std::string> tiles;
  const RasterPart* first = nullptr;
  for (const std::string& file : files) {
    RasterPart part = read_raster_part(file);
    if (first) check_same_raster(part, *first);
    const int index = part.identity.index;
    place_tile(tiles, index, part.identity.count, file);
    const RasterPart& placed = parts.emplace(index, std::move(part)).first->second;
    if (!first) first = &placed;
  }
  const int count = first->identity.count;
  check_no_tile_missing(tiles, count);
  // The tiles' rows join into the whole raster's, each part's after the one before.
  int row = 0;
  for (const auto& [index, part] : parts) {
    if (part.identity.first_row != row) {
      throw part.fail("corrupt part (its rows " + std::to_string(part.identity.first_row) + ".." +
                      std::to_string(part.identity.end_row - 1) + " do not follow the tile before it, which ends at row " +
                      std::to_string(row - 1) + ")");
    }
    row = part.identity.end_row;
  }
  if (row != first->identity.height) {
    throw parts.rbegin()->second.fail("corrupt part (the last tile ends before the raster's last row)");
  }
  PartIndexSummary summary;
  summary.parts = count;
  summary.level = first->identity.level;
  summary.raster = std::to_string(first->identity.width) + " x " + std::to_string(first->identity.height) +
                   " pixels, bands " + join_with_commas(first->identity.layers);
  write_index_text(path, raster_index_xml(parts, destination), destination);
  return summary;
}

}  // namespace qtmv::pipeline
