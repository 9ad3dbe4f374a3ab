// A SQLite database file written behind its connection: the connection's thread copies each page
// it writes into a queue and goes on with the next rows, while a thread of the file's own hands
// the queue to the file system. Writing a large GeoPackage, the kernel's copy of the pages into
// its cache and the file system's block allocation were about half of the rows' time on the one
// thread SQLite writes on (bench/RESULTS.md, session 25); behind the connection they overlap it.
//
// The file is the same, byte for byte: the writes reach it in the order they were made, and every
// call that could see the file as it is (a read of a range still queued, the size, a sync, a
// truncation, a file control, the end of a lock, the close) first waits for the writes before it.
// The first write that fails (a full disk: SQLITE_FULL) is returned by the next call on the file,
// and the writes after it are dropped. The commit waits for every write (at SQLITE_FCNTL_SYNC,
// which SQLite sends even with synchronous=OFF, and at the end of its lock) and fails with it, so
// the connection fails as it would have, a little later, and the run removes its temporary file.
// (The close waits and returns the failure too, but SQLite ignores what a close returns: safety
// rests on the commit.)
//
// How: a VFS of our own (SQLite's "virtual file system", the layer under every connection) wraps
// the default one and is made the default while a SqliteWriteBehind lives. GDAL's GeoPackage and
// SQLite drivers open a plain file with the default VFS. Every file but the ones named is the
// default VFS's own, untouched; a database in WAL mode (shared memory) goes back to writing at
// once, since other connections then read the file without its locks.
#pragma once

#include <cstdint>
#include <string>

namespace qtmv::write {

/// While it lives, the SQLite database at `path` (its main file, opened by a connection of this
/// process after the guard was made) is written behind its connection. Guards may overlap, for
/// several files, and be made on any thread.
class SqliteWriteBehind {
 public:
  explicit SqliteWriteBehind(const std::string& path);
  ~SqliteWriteBehind();
  SqliteWriteBehind(const SqliteWriteBehind&) = delete;
  SqliteWriteBehind& operator=(const SqliteWriteBehind&) = delete;

  /// What the files written behind did so far in this process (for traces and tests).
  struct Totals {
    std::uint64_t bytes = 0;       ///< written to the files by their threads (bytes)
    double waited_seconds = 0;     ///< the connections' time waiting for the file (seconds)
    std::uint64_t drains = 0;      ///< the calls that waited for every write before them to land
  };
  static Totals totals();

  /// The fault switch that makes a file's thread fail its writes, as a full disk does, once it has
  /// written this many bytes (for tests).
  static constexpr const char* kFaultBytes = "QTMV_FAULT_WRITE_BEHIND_BYTES";

 private:
  std::string full_path_;
};

}  // namespace qtmv::write
