// Tile products: what a tile job (-tile K/N) writes and a merge (-merge) joins. A tile is one of
// the N parts of a level that grid::tile_range gives (whole octant rows, in code order); its
// products are the outline cells and cells per site of its codes (label/outline_cells.hpp), which
// join by concatenation into exactly those of a whole run. Sites, attributes and options are not
// stored: the merge reads the same source with the same options, and a fingerprint of the sites'
// geometry (what the labeller was given) tells it when they differ.
//
// File layout (little-endian, version 2):
//   header, 64 bytes: "QTMVTILE", u32 version, u32 level, u32 rule (0 exact, 1 cell),
//     u32 tile index (1..N), u32 tile count N, i32 site count, u64 sites' fingerprint,
//     u64 first code, u64 end code, u64 outline cells;
//   outline cells, 12 bytes each (label::OutlineCell): u32 code bits 0-31, u32 code bits 32 and up
//   with the boundary flag in bit 31, i32 site;
//   cells per site, u64 each (site count of them);
//   u64 checksum of every byte before it.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "label/label_input.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::pipeline {

/// File name extension of tile products (a suggestion; any name is read).
constexpr const char* kTileProductExtension = ".qtmt";

/// The products of one tile job.
struct TileProduct {
  int index = 0;  ///< K of -tile K/N (1..N)
  int count = 0;  ///< N
  label::Rule rule = label::Rule::exact;
  std::uint64_t sites_fingerprint = 0;  ///< input_fingerprint of the sites labelled
  label::Outlines outlines;             ///< of grid::tile_range(level, index, count)
};

/// A 64-bit fingerprint of everything the labeller is given (level, sites, pieces, site cells,
/// fixed cells and nodes, in order): equal inputs give equal labels.
std::uint64_t input_fingerprint(const label::LabelInput& input);

/// Writes `product` to `path` (a GDAL file name: local, /vsis3/, ...). Throws VoronoiError naming
/// the path.
void write_tile_product(const std::string& path, const TileProduct& product);

/// What the tiles must match: the run that merges them.
struct MergeExpectation {
  int level = 0;
  label::Rule rule = label::Rule::exact;
  std::int32_t site_count = 0;
  std::uint64_t sites_fingerprint = 0;
  std::string source;  ///< for messages: the source the merge read
};

/// The files that `paths` name: each a tile product, or a directory whose *.qtmt files are taken
/// (in name order). Throws VoronoiError for a path that is neither, or a directory without any.
std::vector<std::string> tile_product_files(const std::vector<std::string>& paths);

/// Reads the tile products of `files` and joins them into the outlines of the whole level.
/// Throws VoronoiError naming the file at fault: one made at another level, with another rule or
/// from other sites; tiles of different splits (N); a tile given twice; tiles missing (listed).
/// `progress` (may be empty) is called with the fraction of files read; false stops with
/// Interrupted.
label::Outlines merge_tile_products(const std::vector<std::string>& files, const MergeExpectation& expect,
                                    const std::function<bool(double)>& progress = {});

}  // namespace qtmv::pipeline
