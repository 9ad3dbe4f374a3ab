// The destination written all or nothing, and GDAL's messages naming it rather than the
// temporary file it is written as.
#pragma once

#include <cpl_error.h>

#include <cpl_vsi.h>
#include <gdal.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {
class DatabaseOutput;
}

namespace qtmv::pipeline {

namespace fs = std::filesystem;

inline bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

/// Replaces every `from` in `text` with `to`.
void replace_all(std::string& text, const std::string& from, const std::string& to);

/// While it lives, GDAL's messages that name `from` (the temporary file) name `to` (the
/// destination) instead; they then go on to the handler below. The writers keep their failures
/// themselves (gdal::ErrorCapture), so this sees their warnings.
class RenameInMessages {
 public:
  RenameInMessages(std::string from, std::string to);
  ~RenameInMessages();
  RenameInMessages(const RenameInMessages&) = delete;
  RenameInMessages& operator=(const RenameInMessages&) = delete;

 private:
  static void CPL_STDCALL handle(CPLErr type, CPLErrorNum number, const char* message);
  std::string from_, to_;
};

/// The destination written all or nothing. The writer makes the dataset in a temporary directory
/// beside the destination; commit() moves it into place, each file with a rename that never
/// replaces a file that appeared meanwhile (another run writing the same destination), the named
/// file last. With -overwrite, the old dataset's files (those GDAL lists for it, and its
/// sidecars: .aux.xml, -wal, -shm, ...) go aside first and are removed only once the new one is in
/// place; a failure puts everything back. A destination that is an existing directory of
/// per-layer files (Shapefile, CSV) keeps every file but the layers written and their sidecars.
/// A GDAL virtual file system destination (/vsimem/, /vsis3/, ...) is written in place, most of
/// them having no rename into a directory; with -overwrite its old files are renamed aside in
/// their directory first (put back on failure, removed on commit), and where the file system
/// cannot rename (/vsizip/) -overwrite is refused, the old dataset kept. A database destination
/// (`database`, from open_database_output) is staged by it instead (database_output.hpp).
class StagedOutput {
 public:
  StagedOutput(std::string destination, bool overwrite);
  /// (The caller includes database_output.hpp.)
  StagedOutput(std::string destination, bool overwrite, std::unique_ptr<DatabaseOutput> database);
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;
  ~StagedOutput();

  /// The path the writer is to create; for a direct write, clears the way with -overwrite.
  const std::string& begin();
  const std::string& write_path() const { return write_path_; }

  /// Moves what the writer made into place (see the class).
  void commit();

 private:
  /// A /vsi destination's old files renamed aside (-overwrite), or a VoronoiError.
  void set_aside_virtual();
  /// The old files renamed back (a failed run).
  void put_back_virtual();

  struct Aside {
    std::string old, aside;
  };
  std::vector<Aside> virtual_aside_;
  std::unique_ptr<DatabaseOutput> database_;
  std::string destination_, write_path_;
  fs::path dir_, temp_dir_;
  bool overwrite_ = false, direct_ = false, exists_ = false, began_ = false, committed_ = false;
};

}  // namespace qtmv::pipeline
