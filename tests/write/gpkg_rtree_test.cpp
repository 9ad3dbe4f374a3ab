// The R-tree filled at once (gpkg_rtree): the same boxes as SQLite's own inserts store, a tree that
// SQLite's rtreecheck() accepts, queries that find what a scan of the boxes finds, and a tree that
// SQLite's own inserts and deletes carry on from.
#include <gtest/gtest.h>

#include <sqlite3.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "write/cell_labels.hpp"
#include "write/gpkg_rtree.hpp"

namespace qtmv::write {
namespace {

constexpr const char* kRTree = "rtree_t_geom";

/// An in-memory database with an empty R-tree laid out as GeoPackage's (id, minx, maxx, miny, maxy).
class RTreeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(sqlite3_open(":memory:", &db_), SQLITE_OK);
    exec(std::string("CREATE VIRTUAL TABLE ") + kRTree + " USING rtree(id, minx, maxx, miny, maxy)");
  }
  void TearDown() override { sqlite3_close(db_); }

  void exec(const std::string& sql) {
    char* error = nullptr;
    ASSERT_EQ(sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error), SQLITE_OK) << sql << ": " << (error ? error : "");
  }

  /// Rows of a query, each row's columns as text (reals to 9 digits: float32 exactly).
  std::vector<std::string> rows(const std::string& sql) {
    std::vector<std::string> out;
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sql;
    while (st && sqlite3_step(st) == SQLITE_ROW) {
      std::string row;
      for (int c = 0; c < sqlite3_column_count(st); ++c) {
        char text[64];
        if (sqlite3_column_type(st, c) == SQLITE_FLOAT) {
          std::snprintf(text, sizeof text, "%.9g", sqlite3_column_double(st, c));
          row += std::string(c ? " " : "") + text;
        } else {
          row += std::string(c ? " " : "") + reinterpret_cast<const char*>(sqlite3_column_text(st, c));
        }
      }
      out.push_back(row);
    }
    sqlite3_finalize(st);
    return out;
  }

  std::string check() { return rows(std::string("SELECT rtreecheck('") + kRTree + "')").at(0); }

  sqlite3* db_ = nullptr;
};

/// Random boxes in lon/lat (degrees), some tiny, some wide, some degenerate.
std::vector<std::array<double, 4>> random_boxes(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90), size(0, 1);
  std::vector<std::array<double, 4>> out;
  for (std::size_t k = 0; k < n; ++k) {
    const double x = lon(rng), y = lat(rng), s = std::pow(size(rng), 4) * (k % 97 == 0 ? 360 : 3);
    out.push_back({x, std::min(180.0, x + s * (k % 5 != 0)), y, std::min(90.0, y + s / 2)});
  }
  return out;
}

TEST_F(RTreeTest, EntriesAreTheBoxesSqliteStores) {
  // SQLite's own inserts against rtree_entry, bound for bound, over values that fall between
  // floats on either side of zero, exact floats, and the ends of lon/lat.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> any(-180, 180), small(-1e-3, 1e-3);
  std::vector<std::array<double, 4>> boxes{{-180, 180, -90, 90}, {0, 0, 0, 0}, {-0.1, 0.1, -1e-300, 1e-300}};
  for (int k = 0; k < 20000; ++k) {
    const bool tiny = k % 3 == 0;
    double a = tiny ? small(rng) : any(rng), b = tiny ? small(rng) : any(rng), c = any(rng) / 2, d = any(rng) / 2;
    boxes.push_back({std::min(a, b), std::max(a, b), std::min(c, d), std::max(c, d)});
  }
  sqlite3_stmt* insert = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db_, (std::string("INSERT INTO ") + kRTree + " VALUES (?, ?, ?, ?, ?)").c_str(), -1, &insert, nullptr), SQLITE_OK);
  for (std::size_t k = 0; k < boxes.size(); ++k) {
    sqlite3_bind_int64(insert, 1, static_cast<sqlite3_int64>(k + 1));
    for (int c = 0; c < 4; ++c) sqlite3_bind_double(insert, c + 2, boxes[k][static_cast<std::size_t>(c)]);
    ASSERT_EQ(sqlite3_step(insert), SQLITE_DONE);
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_stmt* read = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db_, (std::string("SELECT * FROM ") + kRTree + " ORDER BY id").c_str(), -1, &read, nullptr), SQLITE_OK);
  std::size_t k = 0;
  for (; sqlite3_step(read) == SQLITE_ROW; ++k) {
    const auto& b = boxes.at(k);
    const RTreeEntry e = rtree_entry(static_cast<std::int64_t>(k + 1), b[0], b[1], b[2], b[3]);
    const float stored[] = {static_cast<float>(sqlite3_column_double(read, 1)), static_cast<float>(sqlite3_column_double(read, 2)),
                            static_cast<float>(sqlite3_column_double(read, 3)), static_cast<float>(sqlite3_column_double(read, 4))};
    ASSERT_EQ(stored[0], e.min_x) << k;
    ASSERT_EQ(stored[1], e.max_x) << k;
    ASSERT_EQ(stored[2], e.min_y) << k;
    ASSERT_EQ(stored[3], e.max_y) << k;
    // Outward: the float box holds the double box.
    ASSERT_LE(e.min_x, b[0]);
    ASSERT_GE(e.max_x, b[1]);
  }
  sqlite3_finalize(read);
  EXPECT_EQ(k, boxes.size());
}

TEST_F(RTreeTest, LoadedTreeIsValidAndFindsWhatAScanFinds) {
  // Sizes around one node (51 cells of a 1228-byte node), two levels and three.
  for (std::size_t n : {0u, 1u, 50u, 51u, 52u, 2601u, 2602u, 30000u}) {
    SCOPED_TRACE("entries " + std::to_string(n));
    exec(std::string("DROP TABLE ") + kRTree);
    exec(std::string("CREATE VIRTUAL TABLE ") + kRTree + " USING rtree(id, minx, maxx, miny, maxy)");
    const auto boxes = random_boxes(n, static_cast<unsigned>(n));
    std::vector<RTreeEntry> entries;
    // Ids with gaps (features without geometry are not indexed).
    for (std::size_t k = 0; k < n; ++k) entries.push_back(rtree_entry(static_cast<std::int64_t>(3 * k + 1), boxes[k][0], boxes[k][1], boxes[k][2], boxes[k][3]));
    bulk_load_rtree(db_, kRTree, entries);
    EXPECT_EQ(check(), "ok");
    EXPECT_EQ(rows(std::string("SELECT count(*) FROM ") + kRTree).at(0), std::to_string(n));

    // Windows: the ids whose boxes meet them, from the tree and from the entries.
    std::mt19937_64 rng(n + 1);
    std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
    for (int w = 0; w < 20; ++w) {
      const double x = lon(rng), y = lat(rng), x2 = std::min(180.0, x + 20 * (w % 4)), y2 = std::min(90.0, y + 10);
      std::set<std::string> expected;
      for (const RTreeEntry& e : entries) {
        if (e.max_x >= x && e.min_x <= x2 && e.max_y >= y && e.min_y <= y2) expected.insert(std::to_string(e.id));
      }
      char sql[256];
      std::snprintf(sql, sizeof sql, "SELECT id FROM %s WHERE maxx >= %.17g AND minx <= %.17g AND maxy >= %.17g AND miny <= %.17g",
                    kRTree, x, x2, y, y2);
      const std::vector<std::string> got = rows(sql);
      EXPECT_EQ(std::set<std::string>(got.begin(), got.end()), expected) << sql;
      EXPECT_EQ(got.size(), expected.size()) << "an id found twice";
    }

    // SQLite's own edits carry on from the loaded tree.
    if (n == 0) continue;
    exec(std::string("DELETE FROM ") + kRTree + " WHERE id % 2 = 0");
    exec(std::string("INSERT INTO ") + kRTree + " VALUES (1000000, -1, 1, -1, 1)");
    exec(std::string("UPDATE ") + kRTree + " SET minx = minx - 1 WHERE id % 7 = 1");
    EXPECT_EQ(check(), "ok");
    std::size_t odd = 1;  // the new entry
    for (const RTreeEntry& e : entries) odd += e.id % 2;
    EXPECT_EQ(rows(std::string("SELECT count(*) FROM ") + kRTree).at(0), std::to_string(odd));
  }
}

TEST_F(RTreeTest, DefensiveModeIsLeftAsItWas) {
  // GDAL's connections run in SQLite's defensive mode, which refuses writes to shadow tables.
  int defensive = -1;
  ASSERT_EQ(sqlite3_db_config(db_, SQLITE_DBCONFIG_DEFENSIVE, 1, &defensive), SQLITE_OK);
  ASSERT_EQ(defensive, 1);
  const auto boxes = random_boxes(500, 3);
  std::vector<RTreeEntry> entries;
  for (std::size_t k = 0; k < boxes.size(); ++k) entries.push_back(rtree_entry(static_cast<std::int64_t>(k + 1), boxes[k][0], boxes[k][1], boxes[k][2], boxes[k][3]));
  bulk_load_rtree(db_, kRTree, entries);
  EXPECT_EQ(check(), "ok");
  sqlite3_db_config(db_, SQLITE_DBCONFIG_DEFENSIVE, -1, &defensive);
  EXPECT_EQ(defensive, 1);
  // And after a refusal (the tree is no longer empty).
  EXPECT_THROW(bulk_load_rtree(db_, kRTree, entries), WriteError);
  sqlite3_db_config(db_, SQLITE_DBCONFIG_DEFENSIVE, -1, &defensive);
  EXPECT_EQ(defensive, 1);
}

TEST_F(RTreeTest, OnlyAnEmptyTreeIsLoaded) {
  exec(std::string("INSERT INTO ") + kRTree + " VALUES (1, 0, 1, 0, 1)");
  try {
    bulk_load_rtree(db_, kRTree, {rtree_entry(2, 0, 1, 0, 1)});
    FAIL() << "no WriteError";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find(kRTree), std::string::npos) << e.what();
  }
  EXPECT_EQ(rows(std::string("SELECT id FROM ") + kRTree), std::vector<std::string>{"1"});
  EXPECT_THROW(bulk_load_rtree(db_, "rtree_missing", {}), WriteError);
}

}  // namespace
}  // namespace qtmv::write
