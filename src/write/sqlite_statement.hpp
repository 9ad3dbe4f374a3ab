// SQLite helpers of the GeoPackage writers (gpkg_rows, gpkg_rtree): quoted names and prepared
// statements that finalise themselves and throw WriteError.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "write/cell_labels.hpp"

namespace qtmv::write {

/// `name` as an SQL identifier in double quotes (quotes inside doubled).
inline std::string quoted(const std::string& name) {
  std::string out = "\"";
  for (char c : name) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

/// A prepared statement, finalised on the way out.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &statement_, nullptr) != SQLITE_OK) {
      sqlite3_finalize(statement_);
      throw WriteError("SQLite cannot prepare '" + sql + "': " + sqlite3_errmsg(db));
    }
  }
  ~Statement() { sqlite3_finalize(statement_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt* get() const { return statement_; }
  /// Binds a text parameter (1-based) and returns this.
  Statement& text(int index, const std::string& value) {
    sqlite3_bind_text(statement_, index, value.c_str(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
    return *this;
  }
  /// Steps a statement that returns no row, then resets it; throws with `what` on failure.
  void run(const std::string& what) {
    const int rc = sqlite3_step(statement_);
    sqlite3_reset(statement_);
    if (rc != SQLITE_DONE) throw WriteError("SQLite cannot " + what + ": " + sqlite3_errmsg(db_));
  }
  /// The first column of the first row as an integer (0 without a row).
  std::int64_t integer() {
    const std::int64_t value = sqlite3_step(statement_) == SQLITE_ROW ? sqlite3_column_int64(statement_, 0) : 0;
    sqlite3_reset(statement_);
    return value;
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* statement_ = nullptr;
};

/// INSERTs of several rows at once (one a row costs more than the row): `head` is
/// "INSERT INTO t (a, b) VALUES ", each row `columns` parameters. The statement for a full batch
/// of `rows` rows is kept; a shorter last batch gets one of its own.
class MultiRowInsert {
 public:
  MultiRowInsert(sqlite3* db, std::string head, std::size_t columns, std::size_t rows)
      : db_(db), head_(std::move(head)), columns_(columns), rows_(rows) {}
  std::size_t rows() const { return rows_; }
  /// The statement for `n` rows (1 to rows()), its parameters to bind from 1.
  sqlite3_stmt* prepare(std::size_t n) {
    if (n == rows_) {
      if (!full_) full_ = std::make_unique<Statement>(db_, sql(n));
      current_ = full_.get();
    } else {
      partial_ = std::make_unique<Statement>(db_, sql(n));
      current_ = partial_.get();
    }
    return current_->get();
  }
  /// Runs the statement prepare() gave; throws WriteError with `what` on failure.
  void run(const std::string& what) { current_->run(what); }

 private:
  std::string sql(std::size_t n) const {
    std::string out = head_;
    for (std::size_t r = 0; r < n; ++r) {
      out += r ? ", (?" : "(?";
      for (std::size_t c = 1; c < columns_; ++c) out += ", ?";
      out += ")";
    }
    return out;
  }
  sqlite3* db_;
  std::string head_;
  std::size_t columns_, rows_;
  std::unique_ptr<Statement> full_, partial_;
  Statement* current_ = nullptr;
};

}  // namespace qtmv::write
