// Tile products: what a tile job (-tile K/N) writes and a merge (-merge) joins. A tile is one of
// the N parts of a level that grid::tile_range gives (whole octant rows, in code order); its
// products are the outline cells and cells per site of its codes (label/outline_cells.hpp), which
// join by concatenation into exactly those of a whole run. Attributes and options are not
// stored: the merge reads the same source with the same options, and a fingerprint of the sites'
// geometry (each site's pieces, as the labeller was given them) tells it when they differ. A tile
// job that read only the sites near its tile (sites/tile_selection.hpp) lists them by source
// layer and FID, in its site order; the merge maps them to the whole source's sites.
//
// File layout (little-endian, version 2):
//   header, 88 bytes: "QTMVTILE", u32 version, u32 level, u32 rule (0 exact, 1 cell),
//     u32 tile index (1..N), u32 tile count N, i32 site count, u64 sites' fingerprint,
//     u64 first code, u64 end code, u64 outline cells, u64 sites listed (0: the tile's sites are
//     the whole source's; else its site count), u64 the source's features (of its layers, after
//     -where; 0 when not listed), u64 fingerprint of the reading options (0 when not listed);
//   the sites listed, 16 bytes each: i64 FID, u32 source layer, u32 0;
//   outline cells, 12 bytes each (label::OutlineCell): u32 code bits 0-31, u32 code bits 32 and up
//   with the boundary flag in bit 31, i32 site;
//   cells per site, u64 each (site count of them);
//   u64 checksum of every byte before it.
// Version 1 (a fingerprint of the whole input, no list) is refused with a clear message.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "label/label_input.hpp"
#include "label/outline_cells.hpp"
#include "sites/site_options.hpp"

namespace qtmv::pipeline {

/// File name extension of tile products (a suggestion; any name is read).
constexpr const char* kTileProductExtension = ".qtmt";

/// A site of the source: its layer (of -l, 0 for one layer) and FID.
struct SiteKey {
  std::int64_t fid = 0;
  std::uint32_t layer = 0;
  bool operator<(const SiteKey& o) const { return layer != o.layer ? layer < o.layer : fid < o.fid; }
};

/// The products of one tile job.
struct TileProduct {
  int index = 0;  ///< K of -tile K/N (1..N)
  int count = 0;  ///< N
  label::Rule rule = label::Rule::exact;
  std::uint64_t sites_fingerprint = 0;  ///< sites_fingerprint of the sites labelled
  label::Outlines outlines;             ///< of grid::tile_range(level, index, count)
  /// The tile's sites in the whole source, in site order (a subset of it, in its order); empty:
  /// the tile's sites are the whole source's.
  std::vector<SiteKey> sites;
  /// With `sites`: the features of the whole source (after -where), and reading_fingerprint of
  /// the options it was read with; a merge must read the same (a site the tile did not read
  /// cannot be checked by its geometry).
  std::uint64_t source_features = 0;
  std::uint64_t reading = 0;
};

/// A fingerprint of the options that decide which sites a source gives and their geometry.
std::uint64_t reading_fingerprint(const sites::SourceOptions& options);

/// Per site, a 64-bit fingerprint of its geometry as the labeller is given it (its pieces, in
/// order): equal for a site read alone or among others.
std::vector<std::uint64_t> site_fingerprints(const label::LabelInput& input);

/// The fingerprint of the sites `ids` (in that order) of `per_site`; all of them, in order, when
/// `ids` is null.
std::uint64_t sites_fingerprint(const std::vector<std::uint64_t>& per_site, const std::vector<std::int32_t>* ids = nullptr);

/// Writes `product` to `path` (a GDAL file name: local, /vsis3/, ...). Throws VoronoiError naming
/// the path.
void write_tile_product(const std::string& path, const TileProduct& product);

/// What the tiles must match: the run that merges them.
struct MergeExpectation {
  int level = 0;
  label::Rule rule = label::Rule::exact;
  std::int32_t site_count = 0;
  std::vector<std::uint64_t> site_fingerprints;  ///< of the sites read now (site_fingerprints)
  std::vector<SiteKey> site_keys;                ///< of the sites read now, in site order
  std::uint64_t source_features = 0;             ///< features read now (after -where)
  std::uint64_t reading = 0;                     ///< reading_fingerprint of the merge's options
  std::string source;  ///< for messages: the source the merge read
};

/// The tiles of 1..count that are not `present`: their number, and a list of them for a message
/// ("3, 5": the first 20, then "...").
struct MissingTiles {
  int count = 0;
  std::string list;
};
MissingTiles missing_tiles(int count, const std::function<bool(int)>& present);

/// The files that `paths` name for a merge: each a file, or a directory whose files named
/// *`extension` (one of `extensions`) are taken (in name order). Throws VoronoiError for a path
/// that is neither, a file that is not a regular one (a FIFO would block the merge for ever), or
/// a directory without any (`none_found` says what is missing).
std::vector<std::string> merge_input_files(const std::vector<std::string>& paths,
                                           const std::vector<std::string>& extensions, const std::string& none_found);

/// The files that `paths` name: each a tile product, or a directory whose *.qtmt files are taken
/// (in name order). Throws VoronoiError for a path that is neither, or a directory without any.
std::vector<std::string> tile_product_files(const std::vector<std::string>& paths);

/// Reads the tile products of `files` and joins them into the outlines of the whole level.
/// The sites of a tile that lists them are mapped to the merge's (by layer and FID, which must
/// then name one site each, in the same order).
/// Throws VoronoiError naming the file at fault: one made at another level, with another rule or
/// from other sites (or sites in another order); tiles of different splits (N); a tile given twice; tiles missing (listed).
/// `progress` (may be empty) is called with the fraction of files read; false stops with
/// Interrupted.
label::Outlines merge_tile_products(const std::vector<std::string>& files, const MergeExpectation& expect,
                                    const std::function<bool(double)>& progress = {});

}  // namespace qtmv::pipeline
