// Rows written straight into a GeoPackage feature table, through the SQLite connection of the
// GDAL dataset that made the table: the writers' path for every layer of a GeoPackage (regions,
// Voronoi edges and the per-cell layers' millions of rows).
//
// Why: GDAL 3.6's GeoPackage driver takes about 1.6 us per CreateFeature (one INSERT statement a
// row, Integer64 fields bound as text and converted back by SQLite, per-feature checks) plus the
// building of each OGRGeometry; INSERT statements of up to 64 rows take about 0.25 us a row, so the
// 6 million boundary cells of level 11 take about 1.5 s instead of 10 s (bench/RESULTS.md,
// "qtmvoronoi end to end"). A table with a spatial index gets its R-tree filled at once at the end
// (gpkg_rtree.hpp) instead of one row at a time by GDAL's trigger.
//
// The file is the one GDAL would have written: the rows in the same order with the same FIDs
// (the table's AUTOINCREMENT), geometry blobs as GDAL makes them (GpkgGeometry), gpkg_contents'
// extent and last_change, gpkg_ogr_contents' feature count, and the same boxes in the R-tree
// (its nodes differ: packed rather than grown). GDAL's triggers that count features and index
// them one insert at a time are dropped while the rows go in and put back from their own SQL
// afterwards, as GDAL itself does with the first.
//
// Only for a table that GDAL has just made, empty, with no trigger but GDAL's own (the counters
// and its R-tree's): GpkgRows::open returns null otherwise, and for other drivers, and when the
// configuration option QTMV_GPKG_DIRECT_ROWS is NO; the caller then writes OGR features.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "grid/qtm.hpp"
#include "write/gpkg_rtree.hpp"
#include "write/sqlite_statement.hpp"

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

/// An xy envelope (degrees), empty until a point is added.
struct GpkgEnvelope {
  bool empty = true;
  double min_x = 0, max_x = 0, min_y = 0, max_y = 0;

  void add(double x, double y) { add(GpkgEnvelope{false, x, x, y, y}); }
  void add(const GpkgEnvelope& o) {
    if (o.empty) return;
    if (empty) {
      *this = o;
      return;
    }
    min_x = std::min(min_x, o.min_x), max_x = std::max(max_x, o.max_x);
    min_y = std::min(min_y, o.min_y), max_y = std::max(max_y, o.max_y);
  }
};

/// A geometry's GeoPackage blob made ahead (GpkgGeometry::blob, or a block's), and its envelope.
struct GpkgBlob {
  const unsigned char* data = nullptr;
  std::size_t size = 0;
  GpkgEnvelope envelope;
};

/// A geometry as the GeoPackage blob GDAL's GPkgGeometryFromOGR makes for a 2D geometry in
/// EPSG:4326: "GP", version 0, flags (little-endian, and an xy envelope or, for an empty geometry,
/// the empty bit and no envelope), srs_id 4326, the envelope (min x, max x, min y, max y), then
/// the geometry as WKB, little-endian. Built by begin(), the parts, end().
class GpkgGeometry {
 public:
  static constexpr std::uint32_t kPolygon = 3, kMultiLineString = 5, kMultiPolygon = 6;  ///< WKB types

  /// Starts a geometry of WKB type `type` with `parts` parts (a Polygon's rings, a multi-geometry's members).
  void begin(std::uint32_t type, std::uint32_t parts);
  /// A Polygon member of a MultiPolygon, with `rings` rings to follow.
  void polygon(std::uint32_t rings);
  /// A ring of `n` points (degrees; not closed: written closed).
  void ring(const grid::LonLat* points, std::size_t n);
  /// A LineString member of a MultiLineString, of `n` points (degrees).
  void line(const grid::LonLat* points, std::size_t n);
  /// Ends the geometry: writes its header.
  void end();

  const unsigned char* data() const { return bytes_.data(); }
  std::size_t size() const { return bytes_.size(); }
  /// Its points' envelope (empty for an empty geometry).
  const GpkgEnvelope& envelope() const { return envelope_; }
  /// The blob (ended), valid until the next begin().
  GpkgBlob blob() const { return {bytes_.data(), bytes_.size(), envelope_}; }

 private:
  void u32(std::uint32_t v);
  /// A point count and `n` points (degrees), the first repeated at the end when `closed`.
  void points(const grid::LonLat* p, std::size_t n, bool closed);

  std::vector<unsigned char> bytes_;
  GpkgEnvelope envelope_;
};

/// Whether the direct rows are on: the configuration option QTMV_GPKG_DIRECT_ROWS (default YES).
bool gpkg_direct_rows_enabled();

class GpkgRows {
 public:
  /// Rows for `layer` of `dataset` (GeoPackage only), with its geometry and the
  /// attribute fields `fields` (indices in the layer definition, in the order add() gets their
  /// values). Null when the direct path does not apply (see above). Throws WriteError on an
  /// SQLite failure.
  static std::unique_ptr<GpkgRows> open(GDALDataset& dataset, OGRLayer& layer, const std::vector<int>& fields);

  ~GpkgRows();
  GpkgRows(const GpkgRows&) = delete;
  GpkgRows& operator=(const GpkgRows&) = delete;

  /// Adds a row: its geometry's blob and one value per field. The blob is not copied: it must
  /// stay as it is until the next flush() (or finish()), which the caller makes before it lets
  /// a block of blobs go; rows are also written, 64 at a time, as they come.
  void add(const GpkgBlob& geometry, const RowValue* values);

  /// Writes the rows held (their blobs may go after it).
  void flush();

  /// Writes the rows still held, fills the R-tree, puts GDAL's triggers back, sets the feature
  /// count, the extent and the time of the last change. Throws WriteError on an SQLite failure.
  void finish();

 private:
  GpkgRows(sqlite3* db, std::string table, std::string insert_head, std::size_t columns);
  void exec(const std::string& sql);
  [[noreturn]] void fail(const std::string& what) const;


  sqlite3* db_;
  std::string table_;
  std::size_t columns_;  // geometry and attributes
  MultiRowInsert insert_;  // up to 64 rows an INSERT, fewer for many columns (SQLite's parameter limit)
  std::string insert_failed_;  // what a failed INSERT says
  bool finished_ = false;
  std::vector<GpkgBlob> geometries_;  // the pending rows' geometries (the caller's blobs)
  std::vector<RowValue> values_;  // the pending rows' attributes
  std::uint64_t rows_ = 0;
  GpkgEnvelope extent_;  // of every row written
  /// GDAL's triggers that fire on INSERT (name, SQL): dropped while the rows go in.
  std::vector<std::pair<std::string, std::string>> paused_triggers_;
  std::string rtree_;                  // the table's R-tree ("rtree_<table>_<geometry>"), or empty
  std::vector<RTreeEntry> rtree_entries_;  // its entries, loaded at finish()
};

}  // namespace qtmv::write
