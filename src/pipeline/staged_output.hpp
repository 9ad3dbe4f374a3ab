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
#include <string>
#include <system_error>
#include <vector>

#include "pipeline/voronoi_error.hpp"

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

class StagedOutput {
 public:
  StagedOutput(std::string destination, bool overwrite) : destination_(std::move(destination)) {
    if (starts_with(destination_, "/vsi")) {
      // No rename in most virtual file systems: written directly.
      direct_ = true;
      write_path_ = destination_;
      VSIStatBufL stat;
      exists_ = !starts_with(destination_, "/vsistdout") && VSIStatL(destination_.c_str(), &stat) == 0;
      if (exists_ && !overwrite) throw VoronoiError("'" + destination_ + "' exists: use -overwrite to replace it");
      return;
    }
    const fs::path dest(destination_);
    if (dest.filename().empty()) throw VoronoiError("'" + destination_ + "' names no file");
    dir_ = dest.parent_path().empty() ? fs::path(".") : dest.parent_path();
    std::error_code ec;
    if (fs::exists(fs::symlink_status(dest, ec)) && !overwrite) {
      throw VoronoiError("'" + destination_ + "' exists: use -overwrite to replace it");
    }
    if (!fs::is_directory(dir_, ec)) {
      throw VoronoiError("cannot write '" + destination_ + "': no directory '" + dir_.string() + "'");
    }
    std::string pattern = (dir_ / ("." + dest.filename().string() + ".tmpXXXXXX")).string();
    if (!mkdtemp(pattern.data())) {
      throw VoronoiError("cannot write '" + destination_ + "': cannot create a file in '" + dir_.string() +
                         "': " + std::strerror(errno));
    }
    temp_dir_ = pattern;
    write_path_ = (temp_dir_ / dest.filename()).string();
  }

  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  ~StagedOutput() {
    std::error_code ec;
    if (!temp_dir_.empty()) fs::remove_all(temp_dir_, ec);
    // A direct write that failed leaves what the driver made: remove it (best effort).
    if (direct_ && !committed_ && began_ && !starts_with(destination_, "/vsistdout")) {
      VSIUnlink(destination_.c_str());
    }
  }

  /// The path the writer is to create; for a direct write, clears the way with -overwrite.
  const std::string& begin() {
    if (direct_ && exists_) {
      if (GDALDriverH driver = GDALIdentifyDriver(destination_.c_str(), nullptr)) {
        GDALDeleteDataset(driver, destination_.c_str());
      } else {
        VSIUnlink(destination_.c_str());
      }
    }
    began_ = true;
    return write_path_;
  }
  const std::string& write_path() const { return write_path_; }

  /// Renames what the writer made into place.
  void commit() {
    if (direct_) {
      committed_ = true;
      return;
    }
    const fs::path main_name = fs::path(destination_).filename();
    std::vector<fs::path> entries;
    std::error_code ec;
    for (const fs::directory_entry& entry : fs::directory_iterator(temp_dir_, ec)) entries.push_back(entry.path());
    if (ec) throw VoronoiError("cannot write '" + destination_ + "': " + ec.message());
    if (std::find_if(entries.begin(), entries.end(), [&](const fs::path& p) { return p.filename() == main_name; }) ==
        entries.end()) {
      throw VoronoiError("cannot write '" + destination_ + "': the driver made no file of that name");
    }
    // Only the destination and its sidecars (same stem: out.shx, out.png.aux.xml) move; anything
    // else the driver made (a layer per file) would land on files nobody asked to replace.
    const std::string stem = main_name.stem().string() + ".";
    std::string strays;
    for (const fs::path& p : entries) {
      const std::string name = p.filename().string();
      if (p.filename() != main_name && name.rfind(stem, 0) != 0) strays += (strays.empty() ? "" : ", ") + name;
    }
    if (!strays.empty()) {
      throw VoronoiError("cannot write '" + destination_ + "': the driver made other files beside it (" + strays +
                         "); a single-file format holds one layer: use -layers with one layer, or a directory");
    }
    // Sidecars first, the named file last: it appears only when all is in place.
    std::stable_partition(entries.begin(), entries.end(), [&](const fs::path& p) { return p.filename() != main_name; });
    for (const fs::path& from : entries) {
      const fs::path to = dir_ / from.filename();
      if (fs::is_directory(from) && fs::exists(to)) {
        // A dataset that is a directory (-overwrite): the old one goes aside, then away.
        const fs::path old = temp_dir_ / (".old." + from.filename().string());
        fs::rename(to, old, ec);
        if (!ec) {
          fs::rename(from, to, ec);
          // The temporary directory is removed on the way out: bring the old dataset back first.
          std::error_code ignored;
          if (ec) fs::rename(old, to, ignored);
        }
      } else {
        fs::rename(from, to, ec);
      }
      if (ec) {
        throw VoronoiError("cannot write '" + destination_ + "': renaming into '" + to.string() + "': " + ec.message());
      }
    }
    committed_ = true;
  }

 private:
  std::string destination_, write_path_;
  fs::path dir_, temp_dir_;
  bool direct_ = false, exists_ = false, began_ = false, committed_ = false;
};

}  // namespace qtmv::pipeline
