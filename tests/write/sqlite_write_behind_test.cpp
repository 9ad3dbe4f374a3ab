// Files written behind their connection (sqlite_write_behind): the same bytes as written at once,
// under page sizes, journal modes and a cache so small that SQLite reads back pages it has just
// written; a failed write that fails the statement or the commit, and the file's close; other
// files and the default VFS left as they were.
#include <gtest/gtest.h>

#include <cpl_conv.h>
#include <sqlite3.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "common/config_option.hpp"
#include "write/sqlite_write_behind.hpp"

namespace qtmv::write {
namespace {

namespace fs = std::filesystem;

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A fresh path in the test's temporary directory.
fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("qtmv_write_behind_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / name;
  fs::remove(path);
  return path;
}

/// Runs `sql`; returns SQLite's primary result code.
int exec(sqlite3* db, const std::string& sql) {
  return sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) & 0xff;
}

/// Single values of a query, as text.
std::string value(sqlite3* db, const std::string& sql) {
  sqlite3_stmt* st = nullptr;
  std::string out;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK && sqlite3_step(st) == SQLITE_ROW) {
    const unsigned char* text = sqlite3_column_text(st, 0);
    out = text ? reinterpret_cast<const char*>(text) : "null";
  }
  sqlite3_finalize(st);
  return out;
}

struct Workload {
  int page_size;
  const char* journal;
};

/// Writes a database at `path`: rows of blobs up to 30 kB (overflow pages), read back within
/// their transaction with a cache of a few pages (pages written and then read), updated, deleted,
/// a second transaction, a VACUUM (a truncation). Returns what the reads saw.
std::vector<std::string> write_database(const fs::path& path, const Workload& w) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr), SQLITE_OK);
  std::vector<std::string> seen;
  EXPECT_EQ(exec(db, "PRAGMA page_size=" + std::to_string(w.page_size)), SQLITE_OK);
  EXPECT_EQ(exec(db, std::string("PRAGMA journal_mode=") + w.journal), SQLITE_OK);
  EXPECT_EQ(exec(db, "PRAGMA synchronous=OFF"), SQLITE_OK);
  EXPECT_EQ(exec(db, "PRAGMA cache_size=10"), SQLITE_OK);
  EXPECT_EQ(exec(db, "CREATE TABLE t(id INTEGER PRIMARY KEY AUTOINCREMENT, g BLOB, n INTEGER, r REAL)"), SQLITE_OK);
  EXPECT_EQ(exec(db, "CREATE INDEX t_n ON t(n)"), SQLITE_OK);
  std::mt19937_64 random(20261129);
  for (int round = 0; round < 2; ++round) {
    EXPECT_EQ(exec(db, "BEGIN"), SQLITE_OK);
    sqlite3_stmt* insert = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(db, "INSERT INTO t(g, n, r) VALUES (?, ?, ?)", -1, &insert, nullptr), SQLITE_OK);
    for (int k = 0; k < 1500; ++k) {
      std::vector<unsigned char> blob(1 + random() % 30000);
      for (auto& b : blob) b = static_cast<unsigned char>(random());
      sqlite3_bind_blob(insert, 1, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
      sqlite3_bind_int64(insert, 2, static_cast<sqlite3_int64>(random() % 1000));
      sqlite3_bind_double(insert, 3, static_cast<double>(random() % 100000) / 7.0);
      EXPECT_EQ(sqlite3_step(insert), SQLITE_DONE);
      sqlite3_reset(insert);
      if (k % 500 == 499) {
        seen.push_back(value(db, "SELECT sum(length(g)) || ' ' || sum(n) || ' ' || count(*) FROM t"));
        seen.push_back(value(db, "SELECT hex(substr(g, 1000, 16)) FROM t WHERE id = " + std::to_string(k / 2 + 1)));
      }
    }
    sqlite3_finalize(insert);
    EXPECT_EQ(exec(db, "UPDATE t SET g = zeroblob(100 + n) WHERE n % 7 = 0"), SQLITE_OK);
    EXPECT_EQ(exec(db, "DELETE FROM t WHERE n % 11 = 0"), SQLITE_OK);
    seen.push_back(value(db, "SELECT sum(length(g)) || ' ' || count(*) FROM t WHERE n < 500"));
    EXPECT_EQ(exec(db, "COMMIT"), SQLITE_OK);
  }
  EXPECT_EQ(exec(db, "VACUUM"), SQLITE_OK) << sqlite3_errmsg(db);
  seen.push_back(value(db, "PRAGMA integrity_check"));
  seen.push_back(value(db, "SELECT sum(length(g)) || ' ' || sum(n) || ' ' || count(*) FROM t"));
  EXPECT_EQ(sqlite3_close(db), SQLITE_OK);
  return seen;
}

class SqliteWriteBehindTest : public ::testing::TestWithParam<Workload> {};

TEST_P(SqliteWriteBehindTest, WritesTheFileThatSqliteWritesAtOnce) {
  const Workload w = GetParam();
  const std::string tag = std::to_string(w.page_size) + "_" + w.journal;
  const fs::path at_once = scratch("at_once_" + tag + ".db"), later = scratch("behind_" + tag + ".db");
  const std::vector<std::string> seen_at_once = write_database(at_once, w);
  const std::uint64_t before = SqliteWriteBehind::totals().bytes;
  std::vector<std::string> seen_behind;
  {
    const SqliteWriteBehind guard(later.string());
    seen_behind = write_database(later, w);
  }
  const std::string bytes = read_file(later);
  EXPECT_EQ(seen_behind, seen_at_once);
  EXPECT_EQ(seen_behind.end()[-2], "ok");
  EXPECT_GT(bytes.size(), 10u << 20);
  EXPECT_TRUE(bytes == read_file(at_once)) << "the files differ";
  // It was written behind (but in WAL mode): more bytes went through the file's thread than the
  // file holds.
  if (std::string(w.journal) != "WAL") {
    EXPECT_GE(SqliteWriteBehind::totals().bytes - before, bytes.size());
  }
  fs::remove(at_once);
  fs::remove(later);
}

INSTANTIATE_TEST_SUITE_P(PagesAndJournals, SqliteWriteBehindTest,
                         ::testing::Values(Workload{4096, "DELETE"}, Workload{65536, "OFF"}, Workload{65536, "DELETE"},
                                           Workload{4096, "WAL"}),
                         [](const ::testing::TestParamInfo<Workload>& info) {
                           return "Page" + std::to_string(info.param.page_size) + info.param.journal;
                         });

TEST(SqliteWriteBehind, AFailedWriteFailsTheConnectionAsAFullDisk) {
  set_config_lookup(&CPLGetConfigOption);
  const fs::path path = scratch("full.db");
  CPLConfigOptionSetter fault(SqliteWriteBehind::kFaultBytes, "300000", false);
  const SqliteWriteBehind guard(path.string());
  const std::uint64_t before = SqliteWriteBehind::totals().bytes;
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr), SQLITE_OK);
  ASSERT_EQ(exec(db, "PRAGMA journal_mode=OFF"), SQLITE_OK);
  ASSERT_EQ(exec(db, "PRAGMA synchronous=OFF"), SQLITE_OK);
  ASSERT_EQ(exec(db, "CREATE TABLE t(g BLOB)"), SQLITE_OK);
  ASSERT_EQ(exec(db, "BEGIN"), SQLITE_OK);
  // 20 MB of rows: the cache spills to the file long before the commit.
  int failed = SQLITE_OK;
  for (int k = 0; k < 2000 && failed == SQLITE_OK; ++k) failed = exec(db, "INSERT INTO t VALUES (randomblob(10000))");
  if (failed == SQLITE_OK) failed = exec(db, "COMMIT");
  EXPECT_EQ(failed, SQLITE_FULL) << sqlite3_errmsg(db);
  sqlite3_close(db);
  EXPECT_LE(SqliteWriteBehind::totals().bytes - before, 300000u);
  EXPECT_LT(fs::file_size(path), 1u << 20);  // not the 20 MB of rows
  fs::remove(path);
  set_config_lookup(nullptr);
}

TEST(SqliteWriteBehind, RowsAppendedWaitForTheFileOnlyAtTheirCommit) {
  // A GeoPackage's rows: one transaction of appends, with SQLite's default cache, which spills
  // its pages (and hints the file's growth) all along; the connection must not wait for the file
  // before the commit, or nothing overlaps.
  const fs::path path = scratch("append.db");
  const SqliteWriteBehind guard(path.string());
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr), SQLITE_OK);
  for (const char* sql : {"PRAGMA page_size=65536", "PRAGMA journal_mode=OFF", "PRAGMA synchronous=OFF",
                          "CREATE TABLE t(id INTEGER PRIMARY KEY AUTOINCREMENT, g BLOB)", "BEGIN"}) {
    ASSERT_EQ(exec(db, sql), SQLITE_OK) << sql;
  }
  const SqliteWriteBehind::Totals before = SqliteWriteBehind::totals();
  for (int k = 0; k < 4000; ++k) ASSERT_EQ(exec(db, "INSERT INTO t(g) VALUES (randomblob(11000))"), SQLITE_OK);
  const SqliteWriteBehind::Totals appended = SqliteWriteBehind::totals();
  ASSERT_EQ(exec(db, "COMMIT"), SQLITE_OK);
  EXPECT_EQ(appended.drains, before.drains);
  EXPECT_GT(appended.bytes - before.bytes, 0u);  // the cache spilled: the file's thread wrote
  // The commit waited for every write: the file holds the rows before the connection closes.
  EXPECT_GE(fs::file_size(path), 44000000u);
  EXPECT_EQ(value(db, "SELECT count(*) || ' ' || sum(length(g)) FROM t"), "4000 44000000");
  sqlite3_close(db);
  fs::remove(path);
}

TEST(SqliteWriteBehind, OtherFilesAndTheDefaultVfsAreLeftAsTheyWere) {
  const std::string default_vfs = sqlite3_vfs_find(nullptr)->zName;
  const fs::path named = scratch("named.db"), other = scratch("other.db");
  {
    const SqliteWriteBehind guard(named.string());
    EXPECT_NE(std::string(sqlite3_vfs_find(nullptr)->zName), default_vfs);
    const std::uint64_t before = SqliteWriteBehind::totals().bytes;
    write_database(other, {4096, "DELETE"});
    EXPECT_EQ(SqliteWriteBehind::totals().bytes, before);
    {
      // A second guard of the same file, made and gone inside the first: the first still holds.
      const SqliteWriteBehind again(named.string());
    }
    write_database(named, {4096, "OFF"});
    EXPECT_GT(SqliteWriteBehind::totals().bytes, before);
  }
  EXPECT_EQ(std::string(sqlite3_vfs_find(nullptr)->zName), default_vfs);
  fs::remove(named);
  fs::remove(other);
}

}  // namespace
}  // namespace qtmv::write
