#include "write/gpkg_rows.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

#include <cpl_conv.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include "write/cell_labels.hpp"

namespace qtmv::write {
namespace {

constexpr std::size_t kRowsPerStatement = 64;  // 3 to 5 columns: far under SQLite's 32766 parameters
// Header (8), envelope (32), WKB polygon of one ring (9 + 4) with at most 5 points (16 each).
constexpr std::size_t kMaxBlob = 8 + 32 + 13 + (grid::kMaxPolygonCorners + 1) * 16;

std::string quoted(const std::string& name) {
  std::string out = "\"";
  for (char c : name) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

/// A prepared statement, finalised on the way out.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &statement_, nullptr) != SQLITE_OK) {
      sqlite3_finalize(statement_);
      throw WriteError("SQLite cannot prepare '" + sql + "': " + sqlite3_errmsg(db));
    }
  }
  ~Statement() { sqlite3_finalize(statement_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt* get() const { return statement_; }
  sqlite3_stmt* release() { return std::exchange(statement_, nullptr); }
  /// Binds a text parameter (1-based) and returns this.
  Statement& text(int index, const std::string& value) {
    sqlite3_bind_text(statement_, index, value.c_str(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
    return *this;
  }

 private:
  sqlite3_stmt* statement_ = nullptr;
};

/// Little-endian stores, whatever the host's order.
unsigned char* put_u32(unsigned char* out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) *out++ = static_cast<unsigned char>(v >> (8 * k));
  return out;
}
unsigned char* put_f64(unsigned char* out, double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  for (int k = 0; k < 8; ++k) *out++ = static_cast<unsigned char>(bits >> (8 * k));
  return out;
}

}  // namespace

std::unique_ptr<GpkgRows> GpkgRows::open(GDALDataset& dataset, OGRLayer& layer, const std::vector<int>& fields) {
  if (!CPLTestBool(CPLGetConfigOption("QTMV_GPKG_DIRECT_ROWS", "YES"))) return nullptr;
  if (!dataset.GetDriver() || !EQUAL(dataset.GetDriver()->GetDescription(), "GPKG")) return nullptr;
  // GDAL makes the table at the first feature or at a sync.
  if (layer.SyncToDisk() != OGRERR_NONE) return nullptr;
  auto* db = static_cast<sqlite3*>(dataset.GetInternalHandle("SQLITE_HANDLE"));
  if (!db) return nullptr;
  const std::string table = layer.GetName();

  // No rows yet, and no trigger but GDAL's feature counters (an R-tree's would need our rows).
  std::string count_trigger_sql;
  {
    Statement triggers(db, "SELECT name, sql FROM sqlite_master WHERE type = 'trigger' AND lower(tbl_name) = lower(?)");
    triggers.text(1, table);
    while (sqlite3_step(triggers.get()) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(triggers.get(), 0));
      const auto* sql = reinterpret_cast<const char*>(sqlite3_column_text(triggers.get(), 1));
      const std::string n = name ? name : "";
      if (n == "trigger_delete_feature_count_" + table) continue;
      if (n != "trigger_insert_feature_count_" + table || !sql) return nullptr;
      count_trigger_sql = sql;
    }
    Statement rows(db, "SELECT 1 FROM " + quoted(table) + " LIMIT 1");
    if (sqlite3_step(rows.get()) != SQLITE_DONE) return nullptr;
  }

  const char* geometry = layer.GetGeometryColumn();
  if (!geometry || !*geometry) return nullptr;
  std::string head = "INSERT INTO " + quoted(table) + " (" + quoted(geometry);
  for (int f : fields) head += ", " + quoted(layer.GetLayerDefn()->GetFieldDefn(f)->GetNameRef());
  head += ") VALUES ";
  std::unique_ptr<GpkgRows> rows(new GpkgRows(db, table, head, fields.size() + 1));
  rows->count_trigger_sql_ = std::move(count_trigger_sql);
  return rows;
}

GpkgRows::GpkgRows(sqlite3* db, std::string table, std::string insert_head, std::size_t columns)
    : db_(db),
      table_(std::move(table)),
      insert_head_(std::move(insert_head)),
      columns_(columns),
      blobs_(kRowsPerStatement * kMaxBlob),
      blob_size_(kRowsPerStatement),
      values_(kRowsPerStatement * (columns - 1)) {}

GpkgRows::~GpkgRows() { sqlite3_finalize(full_); }

void GpkgRows::fail(const std::string& what) const {
  throw WriteError("SQLite " + what + ": " + sqlite3_errmsg(db_));
}

void GpkgRows::exec(const std::string& sql) {
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) fail("cannot run '" + sql + "'");
}

void GpkgRows::add(const grid::LonLat* ring, int corners, const RowValue* values) {
  // The blob GDAL's GPkgGeometryFromOGR makes for a Polygon: "GP", version 0, flags (xy
  // envelope, little-endian), srs_id 4326, envelope (min x, max x, min y, max y), then WKB.
  double lo_x = ring[0].lon, hi_x = lo_x, lo_y = ring[0].lat, hi_y = lo_y;
  for (int k = 1; k < corners; ++k) {
    lo_x = std::min(lo_x, ring[k].lon);
    hi_x = std::max(hi_x, ring[k].lon);
    lo_y = std::min(lo_y, ring[k].lat);
    hi_y = std::max(hi_y, ring[k].lat);
  }
  unsigned char* const blob = blobs_.data() + pending_ * kMaxBlob;
  unsigned char* out = blob;
  *out++ = 'G';
  *out++ = 'P';
  *out++ = 0;     // version
  *out++ = 0x03;  // envelope [minx, maxx, miny, maxy], little-endian
  out = put_u32(out, 4326);
  for (double v : {lo_x, hi_x, lo_y, hi_y}) out = put_f64(out, v);
  *out++ = 1;  // WKB little-endian
  out = put_u32(out, 3);  // Polygon
  out = put_u32(out, 1);  // one ring
  out = put_u32(out, static_cast<std::uint32_t>(corners + 1));
  for (int k = 0; k <= corners; ++k) {
    out = put_f64(out, ring[k % corners].lon);
    out = put_f64(out, ring[k % corners].lat);
  }
  blob_size_[pending_] = static_cast<int>(out - blob);
  std::copy(values, values + (columns_ - 1), values_.begin() + static_cast<std::ptrdiff_t>(pending_ * (columns_ - 1)));

  if (rows_ + pending_ == 0) {
    min_x_ = lo_x, max_x_ = hi_x, min_y_ = lo_y, max_y_ = hi_y;
  } else {
    min_x_ = std::min(min_x_, lo_x), max_x_ = std::max(max_x_, hi_x);
    min_y_ = std::min(min_y_, lo_y), max_y_ = std::max(max_y_, hi_y);
  }
  if (++pending_ == kRowsPerStatement) flush();
}

void GpkgRows::flush() {
  if (pending_ == 0) return;
  if (rows_ == 0 && !count_trigger_sql_.empty()) {
    // GDAL drops it too while it writes (it counts one row at a time), and puts it back after.
    exec("DROP TRIGGER " + quoted("trigger_insert_feature_count_" + table_));
  }
  const auto insert_sql = [&](std::size_t rows) {
    std::string sql = insert_head_;
    for (std::size_t r = 0; r < rows; ++r) {
      sql += r ? ", (?" : "(?";
      for (std::size_t c = 1; c < columns_; ++c) sql += ", ?";
      sql += ")";
    }
    return sql;
  };
  std::unique_ptr<Statement> partial;  // the last rows of the table
  if (pending_ == kRowsPerStatement && !full_) full_ = Statement(db_, insert_sql(kRowsPerStatement)).release();
  if (pending_ < kRowsPerStatement) partial = std::make_unique<Statement>(db_, insert_sql(pending_));
  sqlite3_stmt* statement = partial ? partial->get() : full_;

  int parameter = 1, rc = SQLITE_OK;
  for (std::size_t r = 0; r < pending_ && rc == SQLITE_OK; ++r) {
    rc = sqlite3_bind_blob(statement, parameter++, blobs_.data() + r * kMaxBlob, blob_size_[r], SQLITE_STATIC);
    for (std::size_t c = 0; c + 1 < columns_ && rc == SQLITE_OK; ++c) {
      const RowValue& v = values_[r * (columns_ - 1) + c];
      rc = v.kind == RowValue::Kind::integer ? sqlite3_bind_int64(statement, parameter, v.integer)
           : v.kind == RowValue::Kind::real  ? sqlite3_bind_double(statement, parameter, v.real)
           : v.kind == RowValue::Kind::text  ? sqlite3_bind_text(statement, parameter, v.text, -1, SQLITE_STATIC)
                                             : sqlite3_bind_null(statement, parameter);
      ++parameter;
    }
  }
  if (rc != SQLITE_OK) fail("cannot bind a row");
  rc = sqlite3_step(statement);
  sqlite3_reset(statement);
  if (rc != SQLITE_DONE) fail("cannot insert rows into " + quoted(table_));
  rows_ += pending_;
  pending_ = 0;
}

void GpkgRows::finish() {
  flush();
  if (rows_ == 0) return;  // nothing changed: GDAL too leaves the table's entries as they are
  if (!count_trigger_sql_.empty()) {
    exec(count_trigger_sql_);
    Statement count(db_, "UPDATE gpkg_ogr_contents SET feature_count = ? WHERE lower(table_name) = lower(?)");
    sqlite3_bind_int64(count.get(), 1, static_cast<sqlite3_int64>(rows_));
    count.text(2, table_);
    if (sqlite3_step(count.get()) != SQLITE_DONE) fail("cannot set the feature count");
  }
  Statement extent(db_,
                   "UPDATE gpkg_contents SET min_x = ?, min_y = ?, max_x = ?, max_y = ? "
                   "WHERE lower(table_name) = lower(?) AND lower(data_type) = 'features'");
  int k = 1;
  for (double v : {min_x_, min_y_, max_x_, max_y_}) sqlite3_bind_double(extent.get(), k++, v);
  extent.text(5, table_);
  if (sqlite3_step(extent.get()) != SQLITE_DONE) fail("cannot set the extent");
  // As GDAL stamps a changed table: OGR_CURRENT_DATE when set (reproducible files), else now.
  const char* fixed_date = CPLGetConfigOption("OGR_CURRENT_DATE", nullptr);
  Statement stamp(db_, std::string("UPDATE gpkg_contents SET last_change = ") +
                           (fixed_date ? "?" : "strftime('%Y-%m-%dT%H:%M:%fZ','now')") +
                           " WHERE lower(table_name) = lower(?)");
  if (fixed_date) stamp.text(1, fixed_date);
  stamp.text(fixed_date ? 2 : 1, table_);
  if (sqlite3_step(stamp.get()) != SQLITE_DONE) fail("cannot set the time of the last change");
}

}  // namespace qtmv::write
