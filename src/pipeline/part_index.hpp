// Partitioned output: the parts that tile jobs write (-tile K/N -part) and the index that makes
// them one dataset (-merge PARTS -of VRT index.vrt).
//
// A part is a GeoPackage with the vector layers' rows of one tile (grid::tile_range: whole octant
// rows in code order): the regions of its sites cut at the tile's edges (a site's region is the
// union, by site_fid, of its parts), and the per-cell layers' rows of its cells. Its metadata
// (dataset metadata items QTMV_*) keeps what the index checks: the level, the rule, the tile K/N,
// the source and its reading options (a fingerprint) and the layers.
//
// The index is an OGR VRT: per layer, an OGRVRTUnionLayer over that layer of every part (paths
// relative to the index where they can be), with the layer's geometry type, SRS and the parts'
// summed feature count, so that GIS software reads the parts as one dataset without a copy.
//
// A raster part (a raster destination, any GDAL raster format) is a band of rows of the whole
// raster (pipeline/raster_part_index.hpp); its index is a GDAL VRT mosaic of the parts.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "label/label_options.hpp"
#include "pipeline/voronoi_options.hpp"
#include "sites/site_options.hpp"

namespace qtmv::pipeline {

/// What a part is a part of: kept in its metadata, checked by the index.
struct PartIdentity {
  int level = 0;
  label::Rule rule = label::Rule::exact;
  int index = 0, count = 0;  ///< tile K of N
  std::string source;        ///< the source as named to the tile job
  std::uint64_t source_fingerprint = 0;  ///< source_fingerprint of the tile job
  std::vector<std::string> layers;       ///< in the order written; a raster part's: its bands
  /// A raster part: the whole raster's layout ("lonlat" or "qtm") and size (pixels), and the
  /// part's rows [first_row, end_row) of it (pixels, from the top).
  bool raster = false;
  std::string layout;
  int width = 0, height = 0, first_row = 0, end_row = 0;
};

/// A 64-bit fingerprint of what every tile job of one run shares: the source as named, its size
/// and time of change where it is a file (GDAL's VSIStatL), and the reading options. Not the
/// sites read: a tile job may read only those that can own a cell of its tile.
std::uint64_t source_fingerprint(const std::string& source, const sites::SourceOptions& options);

/// The dataset metadata items (NAME, VALUE) that hold `part` (write::VectorOptions::metadata).
std::vector<std::pair<std::string, std::string>> part_metadata(const PartIdentity& part);

/// The part that the metadata `items` (NAME=VALUE, a dataset's metadata list) describe, from the
/// file `path`. Throws VoronoiError naming the file: not a part (no QTMV_PART item), a part of
/// another version, impossible values.
PartIdentity parse_part_metadata(const char* const* items, const std::string& path);

/// Refuses (VoronoiError naming both files) a part `part` (of file `path`) that does not come
/// from the same run as `first` (of file `first_path`): its level, rule, source, reading options
/// or split (N). The layers or bands are checked by the index of their kind.
void check_same_run(const PartIdentity& part, const std::string& path, const PartIdentity& first,
                    const std::string& first_path);

/// The path of the part `part` as the index at `destination` names it, and whether it is relative
/// to the index's directory (where both are local files), else as given.
std::pair<std::string, bool> path_from_index(const std::string& part, const std::string& destination);
/// The items joined with commas ("a,b,c"): a part's layers or bands in messages and metadata.
std::string join_with_commas(const std::vector<std::string>& items);


/// `text` escaped for XML.
std::string xml_escaped(const std::string& text);

/// Writes the index's `text` to `path` (named as `destination` in messages).
void write_index_text(const std::string& path, const std::string& text, const std::string& destination);

/// Refuses (VoronoiError) the tile `index` of `count` at `path` when `tiles` (tile -> path) holds
/// it already; else adds it.
void place_tile(std::map<int, std::string>& tiles, int index, int count, const std::string& path);

/// Refuses (VoronoiError, listing them) the tiles of 1..count that `tiles` lacks.
void check_no_tile_missing(const std::map<int, std::string>& tiles, int count);

/// Whether a run with these options writes an index of parts: -merge with the format VRT, or
/// without a format to a .vrt name.
bool writes_part_index(const std::string& destination, const VoronoiOptions& options);

/// The files that `paths` name: each a part, or a directory whose *.gpkg, *.tif and *.tiff files
/// are taken (in name order). Throws VoronoiError for a path that is neither, or a directory without any.
std::vector<std::string> part_files(const std::vector<std::string>& paths);

/// What write_part_index wrote.
struct PartIndexSummary {
  int parts = 0;
  int level = 0;
  std::vector<std::pair<std::string, std::uint64_t>> layers;  ///< each layer's rows over all parts
  std::string raster;  ///< an index of raster parts: "W x H pixels, bands ..."; empty: vector
};

/// Reads and checks the parts of `files` (written by -tile K/N -part) and writes their index at
/// `path`: an OGR VRT over vector parts, a GDAL VRT over raster parts (write_raster_part_index); paths to the parts are relative to `destination`'s directory
/// where both are local files (the index is moved there), named as `destination` in messages.
/// Throws VoronoiError naming the file at fault: not a part; a part of another level, rule, source
/// (or reading options), layers or split (N) than the first; a part of the other kind (raster or
/// vector) than the first; a tile given twice; tiles missing (listed).
PartIndexSummary write_part_index(const std::vector<std::string>& files, const std::string& path,
                                  const std::string& destination);

}  // namespace qtmv::pipeline
