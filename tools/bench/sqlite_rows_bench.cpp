// The GeoPackage writer's rows alone: N rows of a blob the size of a region at level 16 (11.3 kB),
// an integer and a real, appended in one transaction to a fresh SQLite file with 64 KiB pages, no
// journal and no sync (as the tool writes its temporary GeoPackage), written from SQLite's thread
// ("at once") and behind it (write/sqlite_write_behind.hpp), alternated.
//
//   sqlite_rows_bench [--rows N] [--bytes B] [--repeat R] FILE
//
// Prints, for each way, the median wall time of R runs (seconds, insert to close) and the rate.
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "write/sqlite_write_behind.hpp"

namespace {

/// Seconds to write the rows to `path`, behind or not.
double write_rows(const std::string& path, long rows, std::size_t bytes, bool behind) {
  unlink(path.c_str());
  sync();
  std::unique_ptr<qtmv::write::SqliteWriteBehind> guard;
  if (behind) guard = std::make_unique<qtmv::write::SqliteWriteBehind>(path);
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) {
    std::fprintf(stderr, "sqlite_rows_bench: cannot open %s\n", path.c_str());
    std::exit(1);
  }
  for (const char* sql : {"PRAGMA page_size=65536", "PRAGMA journal_mode=OFF", "PRAGMA synchronous=OFF",
                          "CREATE TABLE t(id INTEGER PRIMARY KEY AUTOINCREMENT, g BLOB, n INTEGER, r REAL)", "BEGIN"}) {
    sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  }
  std::vector<unsigned char> blob(bytes);
  std::mt19937 random(1);
  for (auto& b : blob) b = static_cast<unsigned char>(random());
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO t(g, n, r) VALUES (?, ?, ?)", -1, &insert, nullptr);
  const auto start = std::chrono::steady_clock::now();
  for (long k = 0; k < rows; ++k) {
    blob[static_cast<std::size_t>(k) % bytes] ^= 1;  // no two rows alike
    sqlite3_bind_blob(insert, 1, blob.data(), static_cast<int>(bytes), SQLITE_STATIC);
    sqlite3_bind_int64(insert, 2, k);
    sqlite3_bind_double(insert, 3, static_cast<double>(k) * 0.5);
    if (sqlite3_step(insert) != SQLITE_DONE) {
      std::fprintf(stderr, "sqlite_rows_bench: %s\n", sqlite3_errmsg(db));
      std::exit(1);
    }
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  const bool committed = sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr) == SQLITE_OK;
  sqlite3_close(db);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!committed) {
    std::fprintf(stderr, "sqlite_rows_bench: the commit failed\n");
    std::exit(1);
  }
  unlink(path.c_str());
  return seconds;
}

}  // namespace

int main(int argc, char** argv) {
  long rows = 300000;
  std::size_t bytes = 11300;
  int repeat = 3;
  std::string path;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--rows" && k + 1 < argc) {
      rows = std::atol(argv[++k]);
    } else if (a == "--bytes" && k + 1 < argc) {
      bytes = static_cast<std::size_t>(std::atol(argv[++k]));
    } else if (a == "--repeat" && k + 1 < argc) {
      repeat = std::atoi(argv[++k]);
    } else if (path.empty() && a[0] != '-') {
      path = a;
    } else {
      std::fprintf(stderr, "usage: sqlite_rows_bench [--rows N] [--bytes B] [--repeat R] FILE\n");
      return 2;
    }
  }
  if (path.empty() || rows <= 0 || bytes == 0 || repeat <= 0) {
    std::fprintf(stderr, "usage: sqlite_rows_bench [--rows N] [--bytes B] [--repeat R] FILE\n");
    return 2;
  }
  std::vector<double> at_once, behind;
  for (int r = 0; r < repeat; ++r) {
    at_once.push_back(write_rows(path, rows, bytes, false));
    behind.push_back(write_rows(path, rows, bytes, true));
  }
  const double gb = static_cast<double>(rows) * static_cast<double>(bytes) * 1e-9;
  for (auto* way : {&at_once, &behind}) {
    std::sort(way->begin(), way->end());
    const double median = (*way)[way->size() / 2];
    std::printf("%-8s %ld rows of %zu bytes (%.2f GB): median %.3f s of %d (%.2f GB/s)\n",
                way == &at_once ? "at once" : "behind", rows, bytes, gb, median, repeat, gb / median);
  }
  std::printf("ratio at once / behind: %.2f\n", at_once[at_once.size() / 2] / behind[behind.size() / 2]);
  return 0;
}
