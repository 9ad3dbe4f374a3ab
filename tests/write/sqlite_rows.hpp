// The rows of an SQLite query as text, for comparing what the writers put in GeoPackages: each
// column typed (null, i integer, r real to 17 digits, x blob in hex, t text).
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdio>
#include <string>
#include <vector>

namespace qtmv::write::test {

/// The rows `sql` gives on `db`, each `prefix` then its columns.
inline std::vector<std::string> sqlite_rows(sqlite3* db, const std::string& sql, const std::string& prefix = "") {
  std::vector<std::string> out;
  sqlite3_stmt* st = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sql << ": " << sqlite3_errmsg(db);
  while (st && sqlite3_step(st) == SQLITE_ROW) {
    std::string row = prefix;
    for (int c = 0; c < sqlite3_column_count(st); ++c) {
      switch (sqlite3_column_type(st, c)) {
        case SQLITE_NULL: row += " null"; break;
        case SQLITE_INTEGER: row += " i" + std::to_string(sqlite3_column_int64(st, c)); break;
        case SQLITE_FLOAT: {
          char text[64];
          std::snprintf(text, sizeof text, " r%.17g", sqlite3_column_double(st, c));
          row += text;
          break;
        }
        case SQLITE_BLOB: {
          const auto* bytes = static_cast<const unsigned char*>(sqlite3_column_blob(st, c));
          row += " x";
          for (int k = 0; k < sqlite3_column_bytes(st, c); ++k) {
            row += "0123456789abcdef"[bytes[k] >> 4];
            row += "0123456789abcdef"[bytes[k] & 15];
          }
          break;
        }
        default: row += std::string(" t") + reinterpret_cast<const char*>(sqlite3_column_text(st, c));
      }
    }
    out.push_back(row);
  }
  sqlite3_finalize(st);
  return out;
}

}  // namespace qtmv::write::test
