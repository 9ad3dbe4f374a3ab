// Polygon rows written straight into a GeoPackage feature table, through the SQLite connection of
// the GDAL dataset that made the table: the writers' path for the per-cell layers (millions of
// rows).
//
// Why: GDAL 3.6's GeoPackage driver takes about 1.6 us per CreateFeature (one INSERT statement a
// row, Integer64 fields bound as text and converted back by SQLite, per-feature checks); INSERT
// statements of 64 rows each take about 0.25 us a row, so the 6 million boundary cells of level
// 11 take about 1.5 s instead of 10 s (bench/RESULTS.md, "qtmvoronoi end to end").
//
// The file is the one GDAL would have written: the rows in the same order with the same FIDs
// (the table's AUTOINCREMENT), geometry blobs as GDAL makes them (the "GP" header, version 0,
// little-endian, xy envelope, then the WKB Polygon), gpkg_contents' extent and last_change, and
// gpkg_ogr_contents' feature count. GDAL's trigger that counts features one insert at a time is
// dropped while the rows go in and put back from its own SQL afterwards, as GDAL itself does.
//
// Only for a table that GDAL has just made, empty and without a spatial index (an R-tree would
// miss these rows): GpkgRows::open returns null otherwise, and for other drivers, and when the
// configuration option QTMV_GPKG_DIRECT_ROWS is NO; the caller then writes OGR features.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "grid/qtm.hpp"

class GDALDataset;
class OGRLayer;
struct sqlite3;
struct sqlite3_stmt;

namespace qtmv::write {

/// One attribute of a row: null, an integer, a real or a text (not copied: it must outlive the
/// rows' writing).
struct RowValue {
  enum class Kind { null, integer, real, text };
  Kind kind = Kind::null;
  std::int64_t integer = 0;
  double real = 0;
  const char* text = nullptr;

  static RowValue of(std::int64_t v) { return {Kind::integer, v, 0, nullptr}; }
  static RowValue of(double v) { return {Kind::real, 0, v, nullptr}; }
  static RowValue of(const std::string& v) { return {Kind::text, 0, 0, v.c_str()}; }
};

class GpkgRows {
 public:
  /// Rows for `layer` of `dataset` (GeoPackage only), with its polygon geometry and the
  /// attribute fields `fields` (indices in the layer definition, in the order add() gets their
  /// values). Null when the direct path does not apply (see above). Throws WriteError on an
  /// SQLite failure.
  static std::unique_ptr<GpkgRows> open(GDALDataset& dataset, OGRLayer& layer, const std::vector<int>& fields);

  ~GpkgRows();
  GpkgRows(const GpkgRows&) = delete;
  GpkgRows& operator=(const GpkgRows&) = delete;

  /// Adds a row: the polygon of `corners` points (a ring not closed) and one value per field.
  void add(const grid::LonLat* ring, int corners, const RowValue* values);

  /// Writes the rows still held, puts the counting trigger back, sets the feature count, the
  /// extent and the time of the last change. Throws WriteError on an SQLite failure.
  void finish();

 private:
  GpkgRows(sqlite3* db, std::string table, std::string insert_head, std::size_t columns);
  void flush();
  void exec(const std::string& sql);
  [[noreturn]] void fail(const std::string& what) const;

  sqlite3* db_;
  std::string table_, insert_head_;  // INSERT INTO "t" ("geom", "a", ...) VALUES
  std::size_t columns_;               // geometry and attributes
  sqlite3_stmt* full_ = nullptr;      // the statement for kRowsPerStatement rows
  std::vector<unsigned char> blobs_;  // the pending rows' geometry blobs
  std::vector<int> blob_size_;
  std::vector<RowValue> values_;  // the pending rows' attributes
  std::size_t pending_ = 0;
  std::uint64_t rows_ = 0;
  double min_x_ = 0, min_y_ = 0, max_x_ = 0, max_y_ = 0;
  std::string count_trigger_sql_;  // GDAL's insert trigger, dropped while the rows go in
};

}  // namespace qtmv::write
