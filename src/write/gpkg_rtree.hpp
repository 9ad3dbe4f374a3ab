// A GeoPackage spatial index (SQLite's R-tree, the "gpkg_rtree_index" extension) filled at once
// from every row's envelope, instead of one INSERT at a time through GDAL's trigger.
//
// Why: SQLite's R-tree takes one entry at a time (choosing a leaf, splitting, reinserting), about
// 18 us a row measured alone; GDAL 3.6 fills a new layer's R-tree that way (on a background
// thread, copied in when the dataset closes), which was 1.8 s of closing the 135 233 regions of a
// level 15 run (bench/RESULTS.md). Packing the sorted entries into full nodes (Sort-Tile-Recursive,
// the sorts on all cores) and writing the nodes takes about 0.5 us a row, mostly the rowid
// table's rows, which go in in rowid order: appended to its B-tree (in the leaves' order they
// landed all over it, and a million rows took 7 s once the table outgrew SQLite's page cache of a
// GeoPackage's 64 KiB pages). It gives a tree as good for queries.
//
// Layout (SQLite's ext/rtree file format, the same in every SQLite 3): the virtual table `name`
// keeps its nodes in `name_node(nodeno, data)`, node 1 being the root. A node's data is a blob of
// the tree's node size (the root's length): 2 bytes of depth (the root only: 0 when the root is
// a leaf), a 2-byte cell count, then the cells, each an 8-byte id (a row's id in a leaf, a child's
// node number above) and 4 float32 coordinates (min x, max x, min y, max y), all big-endian.
// `name_rowid(rowid, nodeno)` says which leaf holds each row, `name_parent(nodeno, parentnode)`
// the parent of every node but the root. Coordinates are float32 rounded outward as SQLite rounds
// them (rtree_entry), so queries see the boxes GDAL's inserts would have stored.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

struct sqlite3;

namespace qtmv::write {

/// One row's box in an R-tree: its id and float32 bounds.
struct RTreeEntry {
  std::int64_t id;
  float min_x, max_x, min_y, max_y;
};

/// The entry SQLite's R-tree stores for row `id` whose envelope is [min_x, max_x] x [min_y,
/// max_y] (degrees): each bound rounded to float32 as SQLite rounds it (outwards, but for values
/// near float32's smallest, where SQLite's scaling by one ulp falls short).
RTreeEntry rtree_entry(std::int64_t id, double min_x, double max_x, double min_y, double max_y);

/// Fills the R-tree virtual table `name` of `db`, which must be empty (as just created: a root
/// node without cells), with `entries` (ids unique): packed nodes, the rowid and parent tables.
/// Throws WriteError naming the table on an SQLite failure or when it is not empty.
void bulk_load_rtree(sqlite3* db, const std::string& name, std::vector<RTreeEntry> entries);

}  // namespace qtmv::write
