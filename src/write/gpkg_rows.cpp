#include "write/gpkg_rows.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

#include <cpl_conv.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include "write/cell_labels.hpp"
#include "write/sqlite_statement.hpp"

namespace qtmv::write {
namespace {

constexpr std::size_t kRowsPerStatement = 64;  // rows of one INSERT (fewer when SQLite's parameter limit says)
constexpr std::uint32_t kSrsId = 4326;
constexpr std::size_t kHeaderBytes = 8, kEnvelopeBytes = 32;  // "GP", version, flags, srs_id; 4 doubles

constexpr bool kLittleEndianHost = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;

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

// --- GpkgGeometry ------------------------------------------------------------------------------

void GpkgGeometry::u32(std::uint32_t v) {
  unsigned char b[4];
  put_u32(b, v);
  bytes_.insert(bytes_.end(), b, b + 4);
}

void GpkgGeometry::points(const grid::LonLat* p, std::size_t n, bool closed) {
  // Sized once, then stored in place: a point is 16 bytes of the blob and the geometries of a
  // level-15 run hold hundreds of millions of them.
  const std::size_t count = n + (closed && n > 0 ? 1 : 0);
  const std::size_t at = bytes_.size();
  bytes_.resize(at + 4 + 16 * count);
  unsigned char* out = put_u32(bytes_.data() + at, static_cast<std::uint32_t>(count));
  static_assert(sizeof(grid::LonLat) == 16, "a point is two doubles, lon then lat");
  if (kLittleEndianHost) {
    // The blob's order is the host's: the points as they lie, the ring closed by the first.
    std::memcpy(out, p, 16 * n);
    if (count > n) std::memcpy(out + 16 * n, p, 16);
  } else {
    for (std::size_t k = 0; k < count; ++k) {
      const grid::LonLat& q = p[k < n ? k : 0];
      out = put_f64(put_f64(out, q.lon), q.lat);
    }
  }
  if (n == 0) return;
  GpkgEnvelope box{false, p[0].lon, p[0].lon, p[0].lat, p[0].lat};
  for (std::size_t k = 1; k < n; ++k) {
    box.min_x = std::min(box.min_x, p[k].lon), box.max_x = std::max(box.max_x, p[k].lon);
    box.min_y = std::min(box.min_y, p[k].lat), box.max_y = std::max(box.max_y, p[k].lat);
  }
  envelope_.add(box);
}

void GpkgGeometry::begin(std::uint32_t type, std::uint32_t parts) {
  bytes_.assign(kHeaderBytes + kEnvelopeBytes, 0);  // filled by end()
  envelope_ = {};
  bytes_.push_back(1);  // WKB little-endian
  u32(type);
  u32(parts);
}

void GpkgGeometry::polygon(std::uint32_t rings) {
  bytes_.push_back(1);
  u32(kPolygon);
  u32(rings);
}

void GpkgGeometry::ring(const grid::LonLat* p, std::size_t n) { points(p, n, true); }

void GpkgGeometry::line(const grid::LonLat* p, std::size_t n) {
  bytes_.push_back(1);
  u32(2);  // LineString
  points(p, n, false);
}

void GpkgGeometry::end() {
  unsigned char* out = bytes_.data();
  *out++ = 'G';
  *out++ = 'P';
  *out++ = 0;  // version
  if (envelope_.empty) {
    // Empty: the empty bit, no envelope (GDAL writes none for an empty geometry).
    *out++ = 0x10 | 0x01;
    put_u32(out, kSrsId);
    bytes_.erase(bytes_.begin() + kHeaderBytes, bytes_.begin() + kHeaderBytes + kEnvelopeBytes);
    return;
  }
  *out++ = 0x02 | 0x01;  // envelope [min x, max x, min y, max y], little-endian
  out = put_u32(out, kSrsId);
  for (double v : {envelope_.min_x, envelope_.max_x, envelope_.min_y, envelope_.max_y}) out = put_f64(out, v);
}

// --- GpkgRows ----------------------------------------------------------------------------------

bool gpkg_direct_rows_enabled() { return CPLTestBool(CPLGetConfigOption("QTMV_GPKG_DIRECT_ROWS", "YES")); }

std::unique_ptr<GpkgRows> GpkgRows::open(GDALDataset& dataset, OGRLayer& layer, const std::vector<int>& fields) {
  if (!gpkg_direct_rows_enabled()) return nullptr;
  if (!dataset.GetDriver() || !EQUAL(dataset.GetDriver()->GetDescription(), "GPKG")) return nullptr;
  // GDAL makes the table (and its R-tree, when it has a spatial index) at the first feature or at a sync.
  if (layer.SyncToDisk() != OGRERR_NONE) return nullptr;
  auto* db = static_cast<sqlite3*>(dataset.GetInternalHandle("SQLITE_HANDLE"));
  if (!db) return nullptr;
  const std::string table = layer.GetName();
  const char* geometry = layer.GetGeometryColumn();
  if (!geometry || !*geometry) return nullptr;
  const std::string rtree = "rtree_" + table + "_" + geometry;

  // No rows yet, and no trigger but GDAL's: the feature counters, and its R-tree's (of which only
  // the insert trigger fires on an INSERT).
  std::vector<std::pair<std::string, std::string>> paused;
  bool indexed = false;
  {
    Statement triggers(db, "SELECT name, sql FROM sqlite_master WHERE type = 'trigger' AND lower(tbl_name) = lower(?)");
    triggers.text(1, table);
    while (sqlite3_step(triggers.get()) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(triggers.get(), 0));
      const auto* sql = reinterpret_cast<const char*>(sqlite3_column_text(triggers.get(), 1));
      const std::string n = name ? name : "";
      if (n == "trigger_delete_feature_count_" + table || n == rtree + "_delete" ||
          n.rfind(rtree + "_update", 0) == 0) {
        continue;
      }
      if ((n != "trigger_insert_feature_count_" + table && n != rtree + "_insert") || !sql) return nullptr;
      indexed = indexed || n == rtree + "_insert";
      paused.emplace_back(n, sql);
    }
    Statement rows(db, "SELECT 1 FROM " + quoted(table) + " LIMIT 1");
    if (sqlite3_step(rows.get()) != SQLITE_DONE) return nullptr;
    // An R-tree without its insert trigger (GDAL building it some other way) would miss our rows;
    // one with it needs its three shadow tables to be loaded.
    Statement tables(db, "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN (?1, ?2, ?3, ?4)");
    tables.text(1, rtree).text(2, rtree + "_node").text(3, rtree + "_rowid").text(4, rtree + "_parent");
    const std::int64_t rtree_tables = tables.integer();
    if (rtree_tables != (indexed ? 4 : 0)) return nullptr;
  }

  std::string head = "INSERT INTO " + quoted(table) + " (" + quoted(geometry);
  for (int f : fields) head += ", " + quoted(layer.GetLayerDefn()->GetFieldDefn(f)->GetNameRef());
  head += ") VALUES ";
  std::unique_ptr<GpkgRows> rows(new GpkgRows(db, table, head, fields.size() + 1));
  rows->paused_triggers_ = std::move(paused);
  if (indexed) rows->rtree_ = rtree;
  return rows;
}

GpkgRows::GpkgRows(sqlite3* db, std::string table, std::string insert_head, std::size_t columns)
    : db_(db),
      table_(std::move(table)),
      columns_(columns),
      insert_(db, std::move(insert_head), columns,
              std::clamp<std::size_t>(static_cast<std::size_t>(sqlite3_limit(db, SQLITE_LIMIT_VARIABLE_NUMBER, -1)) / columns,
                                      1, kRowsPerStatement)),
      insert_failed_("insert rows into " + quoted(table_)) {
  geometries_.reserve(insert_.rows());
  values_.reserve(insert_.rows() * (columns - 1));
}

GpkgRows::~GpkgRows() {
  // Left unfinished (a failure): GDAL's triggers back, as far as they go (the file is to be
  // removed, but a caller writing in place keeps no table that silently stops counting or indexing).
  if (rows_ == 0 || finished_) return;
  for (const auto& trigger : paused_triggers_) sqlite3_exec(db_, trigger.second.c_str(), nullptr, nullptr, nullptr);
}

void GpkgRows::fail(const std::string& what) const {
  throw WriteError("SQLite " + what + ": " + sqlite3_errmsg(db_));
}

void GpkgRows::exec(const std::string& sql) {
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) fail("cannot run '" + sql + "'");
}

void GpkgRows::add(const GpkgBlob& geometry, const RowValue* values) {
  geometries_.push_back(geometry);
  values_.insert(values_.end(), values, values + (columns_ - 1));
  extent_.add(geometry.envelope);
  if (geometries_.size() == insert_.rows()) flush();
}

void GpkgRows::flush() {
  const std::size_t pending = geometries_.size();
  if (pending == 0) return;
  if (rows_ == 0) {
    // GDAL drops its counter too while it writes (it counts one row at a time), and puts it
    // back after; the R-tree is filled at the end.
    for (const auto& trigger : paused_triggers_) exec("DROP TRIGGER " + quoted(trigger.first));
  }
  sqlite3_stmt* statement = insert_.prepare(pending);

  int parameter = 1, rc = SQLITE_OK;
  for (std::size_t r = 0; r < pending && rc == SQLITE_OK; ++r) {
    const GpkgBlob& blob = geometries_[r];
    rc = sqlite3_bind_blob(statement, parameter++, blob.data, static_cast<int>(blob.size), SQLITE_STATIC);
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
  insert_.run(insert_failed_);
  if (!rtree_.empty()) {
    // One INSERT of several rows into an AUTOINCREMENT table: consecutive FIDs ending at the last.
    const std::int64_t first = sqlite3_last_insert_rowid(db_) - static_cast<std::int64_t>(pending) + 1;
    for (std::size_t r = 0; r < pending; ++r) {
      const GpkgEnvelope& e = geometries_[r].envelope;
      if (!e.empty) rtree_entries_.push_back(rtree_entry(first + static_cast<std::int64_t>(r), e.min_x, e.max_x, e.min_y, e.max_y));
    }
  }
  rows_ += pending;
  geometries_.clear();
  values_.clear();
}

void GpkgRows::finish() {
  flush();
  if (rows_ == 0) return;  // nothing changed: GDAL too leaves the table's entries as they are
  if (!rtree_.empty()) bulk_load_rtree(db_, rtree_, std::move(rtree_entries_));
  for (const auto& trigger : paused_triggers_) exec(trigger.second);
  finished_ = true;
  if (std::any_of(paused_triggers_.begin(), paused_triggers_.end(),
                  [&](const auto& t) { return t.first == "trigger_insert_feature_count_" + table_; })) {
    Statement count(db_, "UPDATE gpkg_ogr_contents SET feature_count = ? WHERE lower(table_name) = lower(?)");
    sqlite3_bind_int64(count.get(), 1, static_cast<sqlite3_int64>(rows_));
    count.text(2, table_);
    count.run("set the feature count");
  }
  if (!extent_.empty) {
    Statement extent(db_,
                     "UPDATE gpkg_contents SET min_x = ?, min_y = ?, max_x = ?, max_y = ? "
                     "WHERE lower(table_name) = lower(?) AND lower(data_type) = 'features'");
    int k = 1;
    for (double v : {extent_.min_x, extent_.min_y, extent_.max_x, extent_.max_y}) sqlite3_bind_double(extent.get(), k++, v);
    extent.text(5, table_);
    extent.run("set the extent");
  }
  // As GDAL stamps a changed table: OGR_CURRENT_DATE when set (reproducible files), else now.
  const char* fixed_date = CPLGetConfigOption("OGR_CURRENT_DATE", nullptr);
  Statement stamp(db_, std::string("UPDATE gpkg_contents SET last_change = ") +
                           (fixed_date ? "?" : "strftime('%Y-%m-%dT%H:%M:%fZ','now')") +
                           " WHERE lower(table_name) = lower(?)");
  if (fixed_date) stamp.text(1, fixed_date);
  stamp.text(fixed_date ? 2 : 1, table_);
  stamp.run("set the time of the last change");
}

}  // namespace qtmv::write
