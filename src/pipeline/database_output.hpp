// A database destination (PostgreSQL, PG:...) written all or nothing: the layers are written as
// tables of a staging schema, and moved into the destination's schema in one transaction at
// the end. A file's staging directory and renames (staged_output.hpp) do not apply to a database.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "pipeline/run_plan.hpp"

namespace qtmv::pipeline {

class SqlConnection;

/// A PostgreSQL destination written all or nothing. The tables of the layers are written into
/// a schema of their own (qtmv_staging_PID_XXXXXXXX, made by begin(), its name given to the
/// writer as the connection's active_schema); commit() then, in one transaction holding an
/// advisory lock on the destination schema, drops the old tables of the layers written
/// (-overwrite; no other table, and none that another object depends on) and moves the new ones
/// in (ALTER TABLE ... SET SCHEMA: their indexes, sequences and geometry_columns rows follow),
/// then drops the staging schema. A run that fails or is stopped drops its staging schema (a
/// killed one leaves it: its name says whose it is); the destination is as it was. A table that
/// appeared meanwhile (another run) is never replaced without -overwrite: the run fails naming it.
class DatabaseOutput {
 public:
  /// Connects and checks, before any work: the destination schema (-lco SCHEMA, else the
  /// connection's active_schema, else the current schema) exists, the layers' tables exist only
  /// with -overwrite (and are tables), and the user may make a schema. Takes SCHEMA out of
  /// `layer_options` (the writer writes into the staging schema). Throws VoronoiError.
  DatabaseOutput(std::string destination, bool overwrite, std::vector<std::string> layers,
                 std::vector<std::string>& layer_options);
  DatabaseOutput(const DatabaseOutput&) = delete;
  DatabaseOutput& operator=(const DatabaseOutput&) = delete;
  ~DatabaseOutput();

  /// Makes the staging schema; returns the connection string the writer is to open.
  const std::string& begin();
  /// Moves the tables into place (see the class); throws VoronoiError, the destination unchanged.
  void commit();

 private:
  /// The destination's existing relations among the layers' names: name -> kind ('r' a table).
  std::vector<std::pair<std::string, char>> existing(SqlConnection& db) const;
  std::string destination_, connection_, schema_, staging_, write_path_;
  std::vector<std::string> layers_;
  bool overwrite_ = false, staged_ = false, committed_ = false;
};

/// The database output of this plan's destination, or nullptr for a file destination. Refuses
/// (VoronoiError) a database the tool cannot write all or nothing: a raster, a driver other than
/// PostgreSQL, a PostgreSQL destination that is not a PG: connection string.
std::unique_ptr<DatabaseOutput> open_database_output(const std::string& destination, bool overwrite, RunPlan& plan);

}  // namespace qtmv::pipeline
