#include "pipeline/staged_output.hpp"

#include <fcntl.h>
#include <stdio.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_string.h>

#include <set>
#include <utility>

#include "gdal/error_capture.hpp"
#include "pipeline/database_output.hpp"

namespace qtmv::pipeline {

void replace_all(std::string& text, const std::string& from, const std::string& to) {
  if (from.empty()) return;
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

RenameInMessages::RenameInMessages(std::string from, std::string to) : from_(std::move(from)), to_(std::move(to)) {
  gdal::push_handler(&RenameInMessages::handle, this);
}

RenameInMessages::~RenameInMessages() { CPLPopErrorHandler(); }

void CPL_STDCALL RenameInMessages::handle(CPLErr type, CPLErrorNum number, const char* message) {
  auto* self = static_cast<RenameInMessages*>(CPLGetErrorHandlerUserData());
  std::string text = message ? message : "";
  replace_all(text, self->from_, self->to_);
  gdal::raise_below(&RenameInMessages::handle, self, type, number, text);
}

namespace {

/// Sidecars GDAL and SQLite name after a dataset's whole file name (out.tif.aux.xml,
/// out.gpkg-wal): they belong to the old dataset whatever its driver lists.
constexpr const char* kNamedSidecars[] = {".aux.xml", ".ovr", ".msk", "-wal", "-shm", "-journal"};

std::error_code errno_code() { return {errno, std::generic_category()}; }

/// Renames `from` to `to` unless `to` exists (then file_exists), atomically where the file system
/// can (Linux's RENAME_NOREPLACE); elsewhere a hard link then unlink for a file, or a check then
/// a rename.
std::error_code rename_no_replace(const fs::path& from, const fs::path& to) {
#ifdef RENAME_NOREPLACE
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) return {};
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP) return errno_code();
#endif
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(from, ec))) {
    if (::link(from.c_str(), to.c_str()) == 0) {
      ::unlink(from.c_str());
      return {};
    }
    if (errno == EEXIST) return errno_code();
  }
  if (fs::exists(fs::symlink_status(to, ec))) return std::make_error_code(std::errc::file_exists);
  fs::rename(from, to, ec);
  return ec;
}

/// The files of the dataset at `path` as GDAL lists them (none when GDAL cannot open it).
std::vector<fs::path> gdal_file_list(const std::string& path) {
  std::vector<fs::path> files;
  CPLPushErrorHandler(CPLQuietErrorHandler);
  if (GDALDatasetH ds = GDALOpenEx(path.c_str(), GDAL_OF_READONLY | GDAL_OF_VECTOR | GDAL_OF_RASTER, nullptr,
                                   nullptr, nullptr)) {
    char** list = GDALGetFileList(ds);
    for (char** name = list; name && *name; ++name) files.emplace_back(*name);
    CSLDestroy(list);
    GDALClose(ds);
  }
  CPLPopErrorHandler();
  CPLErrorReset();
  return files;
}

/// The names of `files` that lie directly in directory `dir` and are not directories.
std::set<std::string> names_in(const std::vector<fs::path>& files, const fs::path& dir) {
  std::set<std::string> names;
  std::error_code ec;
  const fs::path canonical_dir = fs::weakly_canonical(dir, ec);
  for (const fs::path& file : files) {
    std::error_code file_ec;
    if (fs::weakly_canonical(file.parent_path().empty() ? fs::path(".") : file.parent_path(), file_ec) != canonical_dir) {
      continue;
    }
    if (fs::is_directory(fs::symlink_status(file, file_ec))) continue;
    names.insert(file.filename().string());
  }
  return names;
}

/// One dataset's files moved into place, or put back.
class Transaction {
 public:
  Transaction(std::string destination, fs::path aside) : destination_(std::move(destination)), aside_(std::move(aside)) {}
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  ~Transaction() {
    if (!done_) roll_back();
  }

  /// Moves an old file out of the way (into the temporary directory, removed with it).
  void set_aside(const fs::path& old) {
    std::error_code ec;
    if (aside_moves_.empty()) fs::create_directory(aside_, ec);
    const fs::path to = aside_ / old.filename();
    fs::rename(old, to, ec);
    if (ec) fail("moving the old '" + old.string() + "' aside: " + ec.message());
    aside_moves_.push_back({old, to});
  }

  /// Moves a new file in; never over a file that is there.
  void move_in(const fs::path& from, const fs::path& to) {
    const std::error_code ec = rename_no_replace(from, to);
    if (ec == std::errc::file_exists) {
      fail("'" + to.string() + "' appeared while this run was writing (another run writing the same destination?): " +
           "it is left as it is, and this run's output is not kept");
    }
    if (ec) fail("renaming into '" + to.string() + "': " + ec.message());
    in_moves_.push_back({from, to});
  }

  void done() { done_ = true; }

 private:
  struct Move {
    fs::path from, to;
  };

  [[noreturn]] void fail(const std::string& why) {
    roll_back();
    throw VoronoiError("cannot write '" + destination_ + "': " + why);
  }

  void roll_back() {
    std::error_code ignored;
    for (auto m = in_moves_.rbegin(); m != in_moves_.rend(); ++m) fs::rename(m->to, m->from, ignored);
    for (auto m = aside_moves_.rbegin(); m != aside_moves_.rend(); ++m) fs::rename(m->to, m->from, ignored);
    in_moves_.clear();
    aside_moves_.clear();
    done_ = true;
  }

  std::string destination_;
  fs::path aside_;
  std::vector<Move> aside_moves_, in_moves_;
  bool done_ = false;
};

}  // namespace

StagedOutput::StagedOutput(std::string destination, bool overwrite)
    : StagedOutput(std::move(destination), overwrite, nullptr) {}

StagedOutput::StagedOutput(std::string destination, bool overwrite, std::unique_ptr<DatabaseOutput> database)
    : database_(std::move(database)), destination_(std::move(destination)), overwrite_(overwrite) {
  if (database_) return;
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
  // No dot of the name in the staging directory's: GDAL's /vsizip/ takes a path holding
  // ".xlsx/" or ".kmz/" for an archive, and the XLSX and KMZ writers then fail.
  std::string stem = dest.filename().string();
  std::replace(stem.begin(), stem.end(), '.', '_');
  std::string pattern = (dir_ / ("." + stem + ".tmpXXXXXX")).string();
  if (!mkdtemp(pattern.data())) {
    throw VoronoiError("cannot write '" + destination_ + "': cannot create a file in '" + dir_.string() +
                       "': " + std::strerror(errno));
  }
  temp_dir_ = pattern;
  write_path_ = (temp_dir_ / dest.filename()).string();
}

StagedOutput::~StagedOutput() {
  std::error_code ec;
  if (!temp_dir_.empty()) fs::remove_all(temp_dir_, ec);
  // A direct write that failed leaves what the driver made: remove it (best effort), then put
  // the old dataset back.
  if (direct_ && !committed_ && began_ && !starts_with(destination_, "/vsistdout")) {
    VSIUnlink(destination_.c_str());
  }
  if (!committed_) put_back_virtual();
}

void StagedOutput::set_aside_virtual() {
  VSIStatBufL stat;
  const bool directory = VSIStatL(destination_.c_str(), &stat) == 0 && VSI_ISDIR(stat.st_mode);
  // A directory of layers keeps the user's other files: only what GDAL lists for it goes aside.
  std::vector<std::string> old;
  for (const fs::path& file : gdal_file_list(destination_)) {
    if (file.string() != destination_) old.push_back(file.string());
  }
  if (!directory) {
    for (const char* suffix : kNamedSidecars) {
      const std::string name = destination_ + suffix;
      if (VSIStatL(name.c_str(), &stat) == 0) old.push_back(name);
    }
    old.push_back(destination_);
  }
  std::sort(old.begin(), old.end());
  old.erase(std::unique(old.begin(), old.end()), old.end());
  const std::string tag = ".old" + std::to_string(static_cast<long>(::getpid())) + "_";
  for (const std::string& name : old) {
    const std::string aside = CPLFormFilename(CPLGetPath(name.c_str()), (tag + CPLGetFilename(name.c_str())).c_str(), nullptr);
    if (VSIRename(name.c_str(), aside.c_str()) != 0) {
      put_back_virtual();
      throw VoronoiError("cannot write '" + destination_ + "' with -overwrite: its file system cannot rename '" + name +
                         "' aside, and the old dataset is not deleted before the new one is written; it is left as "
                         "it is: remove it first, or write a local file and copy it");
    }
    virtual_aside_.push_back({name, aside});
  }
}

void StagedOutput::put_back_virtual() {
  for (auto a = virtual_aside_.rbegin(); a != virtual_aside_.rend(); ++a) {
    VSIUnlink(a->old.c_str());
    VSIRename(a->aside.c_str(), a->old.c_str());
  }
  virtual_aside_.clear();
}

const std::string& StagedOutput::begin() {
  if (database_) return write_path_ = database_->begin();
  if (direct_ && exists_) set_aside_virtual();
  began_ = true;
  return write_path_;
}

void StagedOutput::commit() {
  if (database_) {
    database_->commit();
    committed_ = true;
    return;
  }
  if (direct_) {
    committed_ = true;
    for (const Aside& a : virtual_aside_) VSIUnlink(a.aside.c_str());
    virtual_aside_.clear();
    return;
  }
  const fs::path dest(destination_);
  const fs::path main_name = dest.filename();
  const fs::path made = temp_dir_ / main_name;
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(made, ec))) {
    throw VoronoiError("cannot write '" + destination_ + "': the driver made no file of that name");
  }
  const bool made_directory = fs::is_directory(made, ec);
  const bool old_directory = fs::is_directory(fs::symlink_status(dest, ec));
  Transaction moves(destination_, temp_dir_ / ".old");

  if (made_directory && old_directory) {
    // A directory of per-layer files (Shapefile, CSV) into the user's directory: the layers
    // written replace theirs (with their old sidecars, a .qix say); every other file stays.
    std::vector<fs::path> entries;
    for (const fs::directory_entry& entry : fs::directory_iterator(made, ec)) entries.push_back(entry.path());
    if (ec) throw VoronoiError("cannot write '" + destination_ + "': " + ec.message());
    std::set<std::string> stems, old;
    for (const fs::path& p : entries) {
      stems.insert(p.stem().string());
      if (fs::exists(fs::symlink_status(dest / p.filename(), ec))) old.insert(p.filename().string());
    }
    for (const std::string& name : names_in(gdal_file_list(destination_), dest)) {
      if (stems.count(fs::path(name).stem().string())) old.insert(name);
    }
    for (const std::string& name : old) moves.set_aside(dest / name);
    for (const fs::path& from : entries) moves.move_in(from, dest / from.filename());
    moves.done();
    committed_ = true;
    return;
  }

  std::vector<fs::path> entries;
  for (const fs::directory_entry& entry : fs::directory_iterator(temp_dir_, ec)) entries.push_back(entry.path());
  if (ec) throw VoronoiError("cannot write '" + destination_ + "': " + ec.message());
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
  if (old_directory) {
    // A user's directory is never replaced by a file.
    throw VoronoiError("cannot write '" + destination_ + "': renaming into '" + destination_ + "': " +
                       std::make_error_code(std::errc::is_a_directory).message());
  }
  if (overwrite_ && fs::exists(fs::symlink_status(dest, ec))) {
    // The whole old dataset goes: the files its driver lists beside it, its named sidecars, and
    // the destination itself.
    std::set<std::string> old = names_in(gdal_file_list(destination_), dir_);
    for (const char* suffix : kNamedSidecars) {
      const std::string name = main_name.string() + suffix;
      if (fs::exists(fs::symlink_status(dir_ / name, ec))) old.insert(name);
    }
    old.insert(main_name.string());
    for (const std::string& name : old) moves.set_aside(dir_ / name);
  }
  // Sidecars first, the named file last: it appears only when all is in place.
  std::stable_partition(entries.begin(), entries.end(), [&](const fs::path& p) { return p.filename() != main_name; });
  for (const fs::path& from : entries) moves.move_in(from, dir_ / from.filename());
  moves.done();
  committed_ = true;
}

}  // namespace qtmv::pipeline
