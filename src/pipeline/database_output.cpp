#include "pipeline/database_output.hpp"

#include <unistd.h>

#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <utility>

#include "gdal/error_capture.hpp"

namespace qtmv::pipeline {

namespace {

std::string quote_identifier(const std::string& name) {
  std::string quoted = "\"";
  for (char c : name) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

std::string quote_literal(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("''") : std::string(1, c);
  return quoted + "'";
}

/// Takes GDAL's own item `key=VALUE` (active_schema, schemas) out of a PG: connection string;
/// returns VALUE (quotes removed), empty when absent.
std::string take_item(std::string& connection, const std::string& key) {
  const std::size_t at = connection.find(key + "=");
  if (at == std::string::npos || (at > 0 && connection[at - 1] != ' ' && connection[at - 1] != ':')) return "";
  std::size_t end = connection.find(' ', at);
  if (end == std::string::npos) end = connection.size();
  std::string value = connection.substr(at + key.size() + 1, end - at - key.size() - 1);
  if (value.size() >= 2 && value.front() == '\'' && value.back() == '\'') value = value.substr(1, value.size() - 2);
  connection.erase(at, end - at);
  while (!connection.empty() && connection.back() == ' ') connection.pop_back();
  return value;
}

/// The destination as messages show it: a password=VALUE item masked.
std::string shown(std::string destination) {
  const std::size_t at = destination.find("password=");
  if (at == std::string::npos) return destination;
  const std::size_t begin = at + 9, end = std::min(destination.find(' ', begin), destination.size());
  return destination.replace(begin, end - begin, "***");
}

/// PostgreSQL's message on one line.
std::string one_line(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

}  // namespace

/// One connection to the destination's database, through GDAL's PostgreSQL driver.
class SqlConnection {
 public:
  using Rows = std::vector<std::vector<std::string>>;

  SqlConnection(const std::string& connection, const std::string& destination) : destination_(destination) {
    gdal::ErrorCapture trap;
    const char* const drivers[] = {"PostgreSQL", nullptr};
    dataset_ = static_cast<GDALDataset*>(
        GDALOpenEx(connection.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE, drivers, nullptr, nullptr));
    if (!dataset_) fail("cannot connect to the database", trap);
  }
  SqlConnection(const SqlConnection&) = delete;
  SqlConnection& operator=(const SqlConnection&) = delete;
  ~SqlConnection() {
    CPLErrorStateBackuper keep_error_state;
    CPLPushErrorHandler(CPLQuietErrorHandler);
    if (in_transaction_) dataset_->RollbackTransaction();
    GDALClose(dataset_);
    CPLPopErrorHandler();
  }

  /// Runs `sql` (`what` names it in a failure); the rows of its result as text.
  Rows run(const std::string& sql, const std::string& what) {
    gdal::ErrorCapture trap;
    Rows rows;
    if (OGRLayer* result = dataset_->ExecuteSQL(sql.c_str(), nullptr, nullptr)) {
      for (const auto& feature : *result) {
        std::vector<std::string> row;
        for (int k = 0; k < feature->GetFieldCount(); ++k) {
          row.emplace_back(feature->IsFieldSetAndNotNull(k) ? feature->GetFieldAsString(k) : "");
        }
        rows.push_back(std::move(row));
      }
      dataset_->ReleaseResultSet(result);
    }
    if (trap.failed()) fail(what, trap);
    return rows;
  }

  void begin_transaction() {
    gdal::ErrorCapture trap;
    if (dataset_->StartTransaction(TRUE) != OGRERR_NONE) fail("cannot start a transaction", trap);
    in_transaction_ = true;
  }

  void commit() {
    gdal::ErrorCapture trap;
    in_transaction_ = false;
    if (dataset_->CommitTransaction() != OGRERR_NONE || trap.failed()) fail("cannot commit the transaction", trap);
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw VoronoiError("cannot write '" + destination_ + "': " + what);
  }

 private:
  [[noreturn]] void fail(const std::string& what, gdal::ErrorCapture& trap) const {
    const std::string why = one_line(trap.take());
    fail(why.empty() ? what : what + ": " + why);
  }

  std::string destination_;
  GDALDataset* dataset_ = nullptr;
  bool in_transaction_ = false;
};

DatabaseOutput::DatabaseOutput(std::string destination, bool overwrite, std::vector<std::string> layers,
                               std::vector<std::string>& layer_options)
    : destination_(std::move(destination)),
      connection_(destination_),
      layers_(std::move(layers)),
      overwrite_(overwrite) {
  const std::string active = take_item(connection_, "active_schema");
  take_item(connection_, "schemas");
  // GDAL 3.6 takes no active_schema after a URI, which the staging needs.
  if (connection_.find("://") != std::string::npos) {
    throw VoronoiError("cannot write '" + shown(destination_) + "': a URI (PG:postgresql://...) cannot name the " +
                       "schema the run stages its tables in: give the connection as keywords, " +
                       "PG:host=HOST port=PORT dbname=NAME user=USER");
  }
  std::string schema_option;
  for (auto o = layer_options.begin(); o != layer_options.end();) {
    if (STARTS_WITH_CI(o->c_str(), "SCHEMA=")) {
      schema_option = o->substr(7);
      o = layer_options.erase(o);
    } else {
      ++o;
    }
  }
  SqlConnection db(destination_, shown(destination_));
  schema_ = !schema_option.empty() ? schema_option : active;
  if (schema_.empty()) schema_ = db.run("SELECT current_schema() AS s", "reading its current schema").at(0).at(0);
  if (schema_.empty()) db.fail("the connection has no current schema: name one with -lco SCHEMA=NAME");
  const SqlConnection::Rows rights = db.run(
      "SELECT (SELECT count(*) FROM pg_namespace WHERE nspname = " + quote_literal(schema_) + ")::text AS present, " +
          "has_database_privilege(current_database(), 'CREATE')::text AS make_schema",
      "reading the schema " + schema_);
  if (rights.at(0).at(0) == "0") db.fail("no schema '" + schema_ + "' in the database (CREATE SCHEMA makes one)");
  if (rights.at(0).at(1) != "true") {
    db.fail("this user may not make a schema in the database (its CREATE privilege), which the run writes its "
            "tables in before moving them into '" + schema_ + "' all at once");
  }
  std::string tables, others;
  const auto add = [](std::string& list, const std::string& name) { list += (list.empty() ? "" : ", ") + name; };
  for (const auto& [name, kind] : existing(db)) add(kind == 'r' ? tables : others, schema_ + "." + name);
  if (!others.empty()) db.fail(others + " exist(s) and are no tables (a view?): they are left as they are");
  if (!tables.empty() && !overwrite_) db.fail("table(s) " + tables + " exist: use -overwrite to replace them");
  // -overwrite never drops what the user made on the old tables: say so now, not after the work.
  for (const auto& [name, kind] : existing(db)) {
    const std::string table = quote_literal(quote_identifier(schema_) + "." + quote_identifier(name));
    const SqlConnection::Rows views =
        db.run("SELECT DISTINCT v.oid::regclass::text AS v FROM pg_depend d JOIN pg_rewrite r ON r.oid = d.objid "
               "JOIN pg_class v ON v.oid = r.ev_class WHERE d.refobjid = " + table + "::regclass AND v.oid <> d.refobjid",
               "reading what depends on table " + schema_ + "." + name);
    if (!views.empty()) {
      db.fail("-overwrite: view " + views[0][0] + " depends on table " + schema_ + "." + name + ", which would " +
              "have to go with it: both are left as they are (drop the view, or write another schema: -lco SCHEMA=NAME)");
    }
  }
}

DatabaseOutput::~DatabaseOutput() {
  if (!staged_ || committed_) return;
  // A failed or stopped run: its staging schema goes, the destination was never touched.
  try {
    CPLErrorStateBackuper keep_error_state;
    CPLPushErrorHandler(CPLQuietErrorHandler);
    try {
      SqlConnection db(destination_, destination_);
      db.run("DROP SCHEMA IF EXISTS " + quote_identifier(staging_) + " CASCADE", "dropping the staging schema");
    } catch (...) {
    }
    CPLPopErrorHandler();
  } catch (...) {
  }
}

std::vector<std::pair<std::string, char>> DatabaseOutput::existing(SqlConnection& db) const {
  std::string names;
  for (const std::string& layer : layers_) names += (names.empty() ? "" : ", ") + quote_literal(layer);
  std::vector<std::pair<std::string, char>> found;
  for (const auto& row : db.run("SELECT c.relname AS name, c.relkind::text AS kind FROM pg_class c JOIN pg_namespace n "
                                "ON n.oid = c.relnamespace WHERE n.nspname = " + quote_literal(schema_) +
                                    " AND c.relname IN (" + names + ") ORDER BY 1",
                                "reading the tables of schema " + schema_)) {
    found.emplace_back(row.at(0), row.at(1).empty() ? '?' : row.at(1)[0]);
  }
  return found;
}

const std::string& DatabaseOutput::begin() {
  std::random_device random;
  char tag[40];
  std::snprintf(tag, sizeof tag, "qtmv_staging_%ld_%08x", static_cast<long>(::getpid()), static_cast<unsigned>(random()));
  staging_ = tag;
  SqlConnection db(destination_, shown(destination_));
  db.run("CREATE SCHEMA " + quote_identifier(staging_), "making the staging schema " + staging_);
  staged_ = true;
  write_path_ = connection_ + " active_schema=" + staging_;
  return write_path_;
}

void DatabaseOutput::commit() {
  SqlConnection db(destination_, shown(destination_));
  db.begin_transaction();
  // Runs writing one schema commit one at a time; each then sees what the others moved in.
  db.run("SELECT pg_advisory_xact_lock(hashtext(" + quote_literal("qtmvoronoi " + schema_) + ")::bigint)::text AS l",
         "waiting for the other runs writing schema " + schema_);
  for (const auto& [name, kind] : existing(db)) {
    const std::string table = schema_ + "." + name;
    if (!overwrite_) {
      db.fail("table " + table + " appeared while this run was writing (another run writing the same destination?): " +
              "it is left as it is, and this run's output is not kept");
    }
    if (kind != 'r') db.fail(table + " is no longer a table: it is left as it is, and this run's output is not kept");
    // No CASCADE: a view of the user's on the old table is never dropped with it.
    db.run("DROP TABLE " + quote_identifier(schema_) + "." + quote_identifier(name), "replacing table " + table);
  }
  const SqlConnection::Rows made =
      db.run("SELECT tablename FROM pg_tables WHERE schemaname = " + quote_literal(staging_), "reading the staged tables");
  for (const std::string& layer : layers_) {
    if (std::none_of(made.begin(), made.end(), [&](const auto& row) { return row.at(0) == layer; })) {
      db.fail("the PostgreSQL driver made no table " + layer);
    }
  }
  for (const auto& row : made) {
    db.run("ALTER TABLE " + quote_identifier(staging_) + "." + quote_identifier(row.at(0)) + " SET SCHEMA " +
               quote_identifier(schema_),
           "moving table " + row.at(0) + " into schema " + schema_);
  }
  db.run("DROP SCHEMA " + quote_identifier(staging_) + " CASCADE", "dropping the staging schema " + staging_);
  db.commit();
  committed_ = true;
}

std::unique_ptr<DatabaseOutput> open_database_output(const std::string& destination, bool overwrite, RunPlan& plan) {
  const bool pg_prefix = STARTS_WITH_CI(destination.c_str(), "PG:");
  if (!is_database_driver(plan.format.driver)) {
    if (pg_prefix) {
      throw VoronoiError("'" + shown(destination) + "': a PostgreSQL connection is written as vector output " +
                         "(PostgreSQL driver), not with " + plan.format.driver);
    }
    return nullptr;
  }
  if (plan.format.driver != "PostgreSQL" || plan.format.raster) {
    throw VoronoiError("-of " + plan.format.driver + ": a database destination is written all or nothing only in " +
                       "PostgreSQL (PG:...); write a file (GPKG, say) and load it with ogr2ogr");
  }
  if (!pg_prefix) {
    throw VoronoiError("'" + destination + "': a PostgreSQL destination is a connection string: PG:dbname=NAME ...");
  }
  if (!plan.vector.dataset_options.empty()) {
    throw VoronoiError("-dsco: a PostgreSQL database has no dataset creation options (-lco names the layers' options)");
  }
  return std::make_unique<DatabaseOutput>(destination, overwrite, plan.vector.layers, plan.vector.layer_options);
}

}  // namespace qtmv::pipeline
