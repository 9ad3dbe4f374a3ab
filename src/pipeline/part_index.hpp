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
#pragma once

#include <cstdint>
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
  std::vector<std::string> layers;       ///< in the order written
};

/// A 64-bit fingerprint of what every tile job of one run shares: the source as named, its size
/// and time of change where it is a file (GDAL's VSIStatL), and the reading options. Not the
/// sites read: a tile job may read only those that can own a cell of its tile.
std::uint64_t source_fingerprint(const std::string& source, const sites::SourceOptions& options);

/// The dataset metadata items (NAME, VALUE) that hold `part` (write::VectorOptions::metadata).
std::vector<std::pair<std::string, std::string>> part_metadata(const PartIdentity& part);

/// Whether a run with these options writes an index of parts: -merge with the format VRT, or
/// without a format to a .vrt name.
bool writes_part_index(const std::string& destination, const VoronoiOptions& options);

/// The files that `paths` name: each a part, or a directory whose *.gpkg files are taken (in name
/// order). Throws VoronoiError for a path that is neither, or a directory without any.
std::vector<std::string> part_files(const std::vector<std::string>& paths);

/// What write_part_index wrote.
struct PartIndexSummary {
  int parts = 0;
  int level = 0;
  std::vector<std::pair<std::string, std::uint64_t>> layers;  ///< each layer's rows over all parts
};

/// Reads and checks the parts of `files` (GeoPackages written by -tile K/N -part) and writes their
/// index, an OGR VRT, at `path`; paths to the parts are relative to `destination`'s directory
/// where both are local files (the index is moved there), named as `destination` in messages.
/// Throws VoronoiError naming the file at fault: not a part; a part of another level, rule, source
/// (or reading options), layers or split (N) than the first; a tile given twice; tiles missing
/// (listed).
PartIndexSummary write_part_index(const std::vector<std::string>& files, const std::string& path,
                                  const std::string& destination);

}  // namespace qtmv::pipeline
