#include "sites/split_read.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "common/config_option.hpp"
#include "common/trace.hpp"
#include "gdal/error_capture.hpp"

namespace qtmv::sites {

namespace {

constexpr std::size_t kMinRangeBytes = std::size_t{256} << 10;  // a part's open is worth its read
constexpr std::size_t kMaxRangeBytes = std::size_t{8} << 20;    // the parts in memory stay small
constexpr std::size_t kRangesPerThread = 8;                      // the threads end together
constexpr std::size_t kScanBlock = std::size_t{1} << 20;
constexpr std::size_t kMostHeaderBytes = std::size_t{1} << 20;
constexpr std::size_t kMinPartFeatures = 8192;  // a GeoPackage part's open is worth its read

/// A file read by offset (pread: any thread, no shared position), closed with it.
class PlainFile {
 public:
  explicit PlainFile(const std::string& path) : fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {}
  ~PlainFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  PlainFile(const PlainFile&) = delete;
  PlainFile& operator=(const PlainFile&) = delete;
  bool ok() const { return fd_ >= 0; }
  /// Reads [offset, offset + size) into `out` (appended); false on a short read or an error.
  bool read(std::size_t offset, std::size_t size, std::string& out) const {
    const std::size_t at = out.size();
    out.resize(at + size);
    std::size_t done = 0;
    while (done < size) {
      const ssize_t got = ::pread(fd_, &out[at + done], size - done, static_cast<off_t>(offset + done));
      if (got <= 0) return false;
      done += static_cast<std::size_t>(got);
    }
    return true;
  }

 private:
  int fd_;
};

/// The start of the first line that starts at `position` or after it (a line starts after a
/// line feed), or `size` when none does; `position` > 0.
std::size_t line_start_from(const PlainFile& file, std::size_t position, std::size_t size) {
  std::string window;
  for (std::size_t at = position - 1; at < size; at += window.size()) {
    window.clear();
    if (!file.read(at, std::min<std::size_t>(64 << 10, size - at), window)) return size;
    if (const void* lf = std::memchr(window.data(), '\n', window.size())) {
      return at + static_cast<std::size_t>(static_cast<const char*>(lf) - window.data()) + 1;
    }
  }
  return size;
}

/// The records GDAL's CSV reader makes of `bytes` (whole lines, no quote, each carriage return
/// before a line feed): its lines but the empty ones, which it skips without an FID.
std::int64_t csv_records(const char* bytes, std::size_t size) {
  std::int64_t records = 0;
  const char* const end = bytes + size;
  for (const char* line = bytes; line < end;) {
    const char* lf = static_cast<const char*>(std::memchr(line, '\n', static_cast<std::size_t>(end - line)));
    const char* const stop = lf ? lf : end;
    const std::size_t length = static_cast<std::size_t>(stop - line) - (stop > line && stop[-1] == '\r' ? 1 : 0);
    records += length > 0;
    line = stop + 1;
  }
  return records;
}

/// What in `bytes` (data lines) could make GDAL read other lines than the line feeds say; empty
/// when nothing does.
std::string unsplittable(const char* bytes, std::size_t size, bool before_more) {
  if (std::memchr(bytes, '"', size)) return "a quote in the data (a quoted field may hold a line break)";
  if (std::memchr(bytes, '\0', size)) return "a NUL byte in the data";
  for (const char* cr = bytes; (cr = static_cast<const char*>(std::memchr(cr, '\r', size - (cr - bytes))));) {
    ++cr;
    if (cr == bytes + size ? !before_more : *cr != '\n') return "a carriage return not before a line feed";
    if (cr == bytes + size) break;
  }
  return {};
}

/// Why the -oo options may not be applied part by part (a guess made from the file's first
/// lines, or one not known to be line by line); empty when they may.
std::string open_option_refusal(const std::vector<std::string>& open_options) {
  static const char* const kLineByLine[] = {"X_POSSIBLE_NAMES", "Y_POSSIBLE_NAMES", "Z_POSSIBLE_NAMES",
                                            "GEOM_POSSIBLE_NAMES", "KEEP_GEOM_COLUMNS", "EMPTY_STRING_AS_NULL",
                                            "MAX_LINE_SIZE"};
  // Not MERGE_SEPARATOR: a line of separators alone may then be no record (no FID) for GDAL.
  for (const std::string& option : open_options) {
    const std::string name = option.substr(0, option.find('='));
    const char* value = option.find('=') == std::string::npos ? "" : option.c_str() + option.find('=') + 1;
    const bool line_by_line =
        std::any_of(std::begin(kLineByLine), std::end(kLineByLine), [&](const char* n) { return EQUAL(n, name.c_str()); }) ||
        (EQUAL(name.c_str(), "AUTODETECT_TYPE") && !CPLTestBool(value)) ||
        (EQUAL(name.c_str(), "HEADERS") && (EQUAL(value, "YES") || EQUAL(value, "AUTO")));
    if (!line_by_line) return "-oo " + option + " (a guess from the file's first lines, or not known to be line by line)";
  }
  return {};
}

/// `text` quoted for SQL with `quote` (' for a string, " for a name), a quote inside doubled.
std::string sql_quoted(const std::string& text, char quote) {
  std::string out(1, quote);
  for (const char c : text) out += c == quote ? std::string(2, c) : std::string(1, c);
  return out + quote;
}

/// A GDAL message raised while reading a part: before the part's feature `at` was returned
/// (`at` == the part's feature count: by the read that found its end).
struct PartMessage {
  std::size_t at;
  CPLErr type;
  CPLErrorNum number;
  std::string text;
};

/// One range of the file read by GDAL: its features in order, its messages, its records.
struct Part {
  std::vector<OGRFeatureUniquePtr> features;
  std::vector<PartMessage> messages;
  std::int64_t records = 0;  // the FIDs it used (its lines but the empty ones)
};

/// The messages GDAL raises on this thread while a part is read, each at the feature it came
/// with (debug output passes by).
class MessageLog {
 public:
  explicit MessageLog(Part& part) : part_(part) { gdal::push_handler(&MessageLog::handle, this); }
  ~MessageLog() { CPLPopErrorHandler(); }
  MessageLog(const MessageLog&) = delete;
  MessageLog& operator=(const MessageLog&) = delete;

 private:
  static void CPL_STDCALL handle(CPLErr type, CPLErrorNum number, const char* message) {
    auto* self = static_cast<MessageLog*>(CPLGetErrorHandlerUserData());
    self->part_.messages.push_back({self->part_.features.size(), type, number, message ? message : ""});
  }
  Part& part_;
};

/// The file read whole once, in parallel: why its data may not be split (empty: it may).
std::string scan_data(const std::string& path, std::size_t data_start, std::size_t size, int threads) {
  const std::size_t blocks = (size - data_start + kScanBlock - 1) / kScanBlock;
  std::vector<std::string> why(blocks);
  std::atomic<bool> found{false};
#pragma omp parallel num_threads(threads)
  {
    const PlainFile file(path);
    std::string bytes;
#pragma omp for schedule(dynamic, 1)
    for (std::size_t b = 0; b < blocks; ++b) {
      if (found.load(std::memory_order_relaxed)) continue;
      const std::size_t at = data_start + b * kScanBlock, end = std::min(size, at + kScanBlock);
      bytes.clear();
      why[b] = !file.ok() || !file.read(at, end - at, bytes) ? "cannot read the file"
                                                             : unsplittable(bytes.data(), bytes.size(), end < size);
      // A carriage return at a block's end is settled by the next block's first byte.
      if (why[b].empty() && end < size && bytes.back() == '\r') {
        std::string next;
        if (!file.read(end, 1, next) || next[0] != '\n') why[b] = "a carriage return not before a line feed";
      }
      if (!why[b].empty()) found = true;
    }
  }
  for (const std::string& w : why) {
    if (!w.empty()) return w;
  }
  return {};
}

/// Reads `path`'s whole small file (a sidecar) into `out`; false when there is none.
bool read_sidecar(const std::string& path, std::string& out) {
  VSIStatBufL stat;
  if (VSIStatL(path.c_str(), &stat) != 0 || !VSI_ISREG(stat.st_mode) || stat.st_size > (16 << 20)) return false;
  const PlainFile file(path);
  return file.ok() && file.read(0, static_cast<std::size_t>(stat.st_size), out);
}

/// A CSV in memory (/vsimem/): `bytes` at `path`, the sidecars beside it (extension, bytes), all
/// referenced, not copied; removed with it.
class MemoryCsv {
 public:
  MemoryCsv(std::string path, const std::string& bytes, const std::vector<std::pair<std::string, std::string>>& sidecars)
      : files_{std::move(path)} {
    add(files_[0], bytes);
    for (const auto& [extension, sidecar] : sidecars) {
      files_.emplace_back(CPLResetExtension(files_[0].c_str(), extension.c_str()));
      add(files_.back(), sidecar);
    }
  }
  ~MemoryCsv() {
    for (const std::string& f : files_) VSIUnlink(f.c_str());
    VSIRmdir(CPLGetPath(files_[0].c_str()));
  }
  MemoryCsv(const MemoryCsv&) = delete;
  MemoryCsv& operator=(const MemoryCsv&) = delete;

  /// Opened by GDAL's CSV driver with `open_options`; null when it does not open.
  GDALDatasetUniquePtr open(const std::vector<std::string>& open_options) const {
    const char* const csv_only[] = {"CSV", nullptr};
    return open_vector(files_[0], open_options, csv_only);
  }

 private:
  static void add(const std::string& path, const std::string& bytes) {
    VSIFCloseL(VSIFileFromMemBuffer(path.c_str(), reinterpret_cast<GByte*>(const_cast<char*>(bytes.data())),
                                    bytes.size(), FALSE));
  }
  std::vector<std::string> files_;
};

std::atomic<std::uint64_t> split_reads{0};  // each split read's /vsimem/ folder its own name

}  // namespace

struct SplitRead::Impl {
  // --- the file, as found by open() ---
  std::string source_path, file_name, header;
  std::vector<std::pair<std::string, std::string>> sidecars;  // extension, bytes
  std::vector<std::string> open_options;
  std::string where;
  std::size_t data_start = 0, size = 0, range_bytes = 0, ranges = 0;
  std::string folder;  // /vsimem/ folder of the parts
  std::unique_ptr<PlainFile> file;
  // A GeoPackage table's ranges of FIDs (rowids) instead of a CSV's ranges of bytes: read in
  // rowid order, as its sequential read (a full scan of the table) is.
  bool by_fid = false;
  std::string layer_name, fid_column;
  GIntBig first_fid = 0, fid_step = 0;
  const OGRFeatureDefn* layer_definition = nullptr;

  // --- the parts' threads ---
  std::mutex mutex;
  std::condition_variable part_ready, room;
  std::vector<std::unique_ptr<Part>> parts;  // by range; handed on and released in order
  std::size_t next_range = 0, consumed = 0, window = 0;
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;

  // --- the reading thread's side ---
  std::unique_ptr<Part> current;
  std::size_t position = 0;     // the next feature of `current`
  std::int64_t fid_shift = 0;   // the records of the parts before `current`
  std::size_t handed = 0;       // the parts handed on (current among them)
  bool ended = false;
  std::vector<std::string> once_warned;  // GDAL's once-a-layer warnings raised so far

  /// A part's dataset and path: the header and the lines of `bytes`, its sidecars beside it.
  std::string part_path(std::size_t r) const { return folder + "/" + std::to_string(r) + "/" + file_name; }

  void read_part(std::size_t r, Part& part);
  void read_fid_range(std::size_t r, Part& part);
  /// Reads `layer`'s features (its filter set) into `part`, until the end or a stop.
  void read_features(OGRLayer& layer, Part& part);
  void read_bytes(std::size_t r, Part& part, const std::string& bytes);
  void work();
  void raise(const PartMessage& message);
};

void SplitRead::Impl::work() {
  for (;;) {
    std::size_t r;
    {
      std::unique_lock<std::mutex> lock(mutex);
      room.wait(lock, [&] { return stop || next_range == ranges || next_range < consumed + window; });
      if (stop || next_range == ranges) return;
      r = next_range++;
    }
    auto part = std::make_unique<Part>();
    try {
      read_part(r, *part);
    } catch (const std::exception& e) {
      part->features.clear();
      part->messages.push_back({0, CE_Failure, CPLE_AppDefined, std::string("split read: ") + e.what()});
    } catch (...) {  // the reading thread must get every part, or it would wait for ever
      part->features.clear();
      part->messages.push_back({0, CE_Failure, CPLE_AppDefined, "split read: unknown failure"});
    }
    {
      const std::lock_guard<std::mutex> lock(mutex);
      parts[r] = std::move(part);
    }
    part_ready.notify_all();
  }
}

void SplitRead::Impl::read_part(std::size_t r, Part& part) {
  if (by_fid) {
    read_fid_range(r, part);
    return;
  }
  const std::size_t nominal = data_start + r * range_bytes;
  const std::size_t start = r == 0 ? data_start : line_start_from(*file, nominal, size);
  const std::size_t end = r + 1 == ranges ? size : line_start_from(*file, nominal + range_bytes, size);
  std::string bytes = header;
  if (start < end && !file->read(start, end - start, bytes)) {
    part.messages.push_back({0, CE_Failure, CPLE_FileIO, "cannot read bytes " + std::to_string(start) + ".." +
                                                             std::to_string(end) + " of '" + source_path + "'"});
    return;
  }
  part.records = csv_records(bytes.data() + header.size(), bytes.size() - header.size());
  read_bytes(r, part, bytes);
}

/// GDAL's CSV driver reads part `r`'s bytes (the header and its lines) from memory.
void SplitRead::Impl::read_bytes(std::size_t r, Part& part, const std::string& bytes) {
  const MemoryCsv csv(part_path(r), bytes, sidecars);
  MessageLog log(part);
  const GDALDatasetUniquePtr dataset = csv.open(open_options);
  OGRLayer* const layer = dataset && dataset->GetLayerCount() == 1 ? dataset->GetLayer(0) : nullptr;
  if (!layer) {
    part.messages.push_back({0, CE_Failure, CPLE_OpenFailed, "cannot read part " + std::to_string(r) + " of the split read"});
  } else if (!where.empty() && layer->SetAttributeFilter(where.c_str()) != OGRERR_NONE) {
    part.messages.push_back({0, CE_Failure, CPLE_AppDefined, "bad -where: " + where});
  } else {
    read_features(*layer, part);
  }
}  // the dataset closed (its features keep its definition) before its files go

void SplitRead::Impl::read_features(OGRLayer& layer, Part& part) {
  GIntBig last_fid = 0;
  while (!stop.load(std::memory_order_relaxed)) {
    OGRFeatureUniquePtr feature(layer.GetNextFeature());
    if (!feature) break;
    // A CSV part's FIDs are shifted by the records before it: that holds only while GDAL numbers
    // a part's features by its non-empty lines, as 3.6 does. Any other numbering (a driver that
    // took an FID column) fails the read loudly rather than give features other FIDs.
    if (!by_fid && (feature->GetFID() <= last_fid || feature->GetFID() > part.records)) {
      part.messages.push_back({part.features.size(), CE_Failure, CPLE_AppDefined,
                               "split read: GDAL gave FID " + std::to_string(feature->GetFID()) +
                                   " to a feature of a part of " + std::to_string(part.records) +
                                   " lines; read it on one thread with --config QTMV_READ_SPLIT NO"});
      break;
    }
    last_fid = feature->GetFID();
    part.features.push_back(std::move(feature));
  }
}

/// The GeoPackage read again (its own SQLite connection) for part `r`'s FIDs, in rowid order.
void SplitRead::Impl::read_fid_range(std::size_t r, Part& part) {
  MessageLog log(part);
  const char* const gpkg_only[] = {"GPKG", nullptr};
  const GDALDatasetUniquePtr dataset = open_vector(source_path, open_options, gpkg_only);
  OGRLayer* const layer = dataset ? dataset->GetLayerByName(layer_name.c_str()) : nullptr;
  const GIntBig from = first_fid + static_cast<GIntBig>(r) * fid_step;
  const std::string filter = sql_quoted(fid_column, '"') + " >= " + std::to_string(from) + " AND " +
                             sql_quoted(fid_column, '"') + " < " + std::to_string(from + fid_step);
  if (!layer || !layer->GetLayerDefn()->IsSame(layer_definition)) {
    part.messages.push_back({0, CE_Failure, CPLE_OpenFailed, "cannot read part " + std::to_string(r) + " of the split read"});
  } else if (layer->SetAttributeFilter(filter.c_str()) != OGRERR_NONE) {
    part.messages.push_back({0, CE_Failure, CPLE_AppDefined, "split read: bad FID filter " + filter});
  } else {
    read_features(*layer, part);
  }
}

/// Raises a part's message on this thread as the sequential read would have: the file's own
/// name, and a once-a-layer warning once, with the record number of the whole file.
void SplitRead::Impl::raise(const PartMessage& message) {
  std::string text = message.text;
  if (!by_fid) {
    const std::string path = part_path(handed - 1);
    for (std::size_t at; (at = text.find(path)) != std::string::npos;) text.replace(at, path.size(), source_path);
  }
  if (text.find("This warning will no longer be emitted") != std::string::npos) {
    std::string key = text;
    const std::size_t record = text.find("record ");
    if (record != std::string::npos) {
      const std::size_t digits = record + 7;
      std::size_t digits_end = digits;
      while (digits_end < text.size() && text[digits_end] >= '0' && text[digits_end] <= '9') ++digits_end;
      key.erase(digits, digits_end - digits);
      if (digits_end > digits) {
        text.replace(digits, digits_end - digits, std::to_string(std::stoll(text.substr(digits, digits_end - digits)) + fid_shift));
      }
    }
    if (std::find(once_warned.begin(), once_warned.end(), key) != once_warned.end()) return;
    once_warned.push_back(key);
  }
  CPLError(message.type, message.number, "%s", text.c_str());
}

namespace {

/// Why a GeoPackage layer is read as one sequence; empty when its FIDs may be split in ranges.
std::string fid_range_refusal(const OgrSource& source, OGRLayer& layer, const ReadOptions& options, int threads,
                              SplitRead::Impl& s) {
  // SQLite may read a filtered table in an index's order, not its rowids'.
  if (!options.where.empty()) return "-where (SQLite may read it in an index's order)";
  const std::string name = layer.GetName(), fid = layer.GetFIDColumn() ? layer.GetFIDColumn() : "";
  if (fid.empty()) return "the layer has no FID column";
  const gdal::ErrorCapture quiet;
  GDALDataset* const dataset = source.dataset.get();
  const std::string sql = "SELECT (SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = " +
                          sql_quoted(name, '\'') + "), MIN(" + sql_quoted(fid, '"') + "), MAX(" + sql_quoted(fid, '"') +
                          "), COUNT(*) FROM " + sql_quoted(name, '"');
  OGRLayer* const result = dataset->ExecuteSQL(sql.c_str(), nullptr, "SQLITE");
  if (!result) return "its FIDs cannot be counted";
  const OGRFeatureUniquePtr row(result->GetNextFeature());
  const bool table = row && row->GetFieldAsInteger64(0) == 1;
  const GIntBig first = row ? row->GetFieldAsInteger64(1) : 0, last = row ? row->GetFieldAsInteger64(2) : 0;
  const GIntBig count = row ? row->GetFieldAsInteger64(3) : 0;
  dataset->ReleaseResultSet(result);
  if (!table) return "not a table (a view is read in its own order)";
  const GIntBig parts = std::min<GIntBig>(static_cast<GIntBig>(threads) * static_cast<GIntBig>(kRangesPerThread),
                                          count / static_cast<GIntBig>(kMinPartFeatures));
  if (parts < 2) return std::to_string(count) + " features";
  s.by_fid = true;
  s.source_path = source.name;
  s.layer_name = name;
  s.fid_column = fid;
  s.first_fid = first;
  s.fid_step = (last - first) / parts + 1;
  s.ranges = static_cast<std::size_t>((last - first) / s.fid_step + 1);
  s.open_options = options.open_options;
  s.layer_definition = layer.GetLayerDefn();
  return {};
}

/// Why `layer` of `source` is read as one sequence; empty when it may be split. Sets `s`'s file,
/// header, sidecars and ranges (or FID ranges, cut for `readers` threads) on the way; the file
/// is scanned on `threads`.
std::string split_refusal(const OgrSource& source, OGRLayer& layer, const ReadOptions& options, int threads,
                          int readers, SplitRead::Impl& s) {
  if (readers < 2) return "the run has one thread";
  if (const char* split = config_option("QTMV_READ_SPLIT"); split && !CPLTestBool(split)) return "QTMV_READ_SPLIT=NO";
  if (!options.sql.empty()) return "-sql";
  std::uint64_t bytes = 0;
  if (!source.plain_file(&bytes)) return "not a plain file";
  if (EQUAL(source.dataset->GetDriverName(), "GPKG")) return fid_range_refusal(source, layer, options, readers, s);
  if (!EQUAL(source.dataset->GetDriverName(), "CSV")) {
    return std::string("the ") + source.dataset->GetDriverName() + " driver's reads are not split";
  }
  if (std::string why = open_option_refusal(options.open_options); !why.empty()) return why;
  if (CPLString(options.where).ifind("fid") != std::string::npos) return "-where names an FID (each part numbers its own)";
  s.source_path = source.name;
  s.file_name = CPLGetFilename(source.name.c_str());
  s.size = static_cast<std::size_t>(bytes);
  s.file = std::make_unique<PlainFile>(source.name);
  // The header line: GDAL's layer definition comes from it (and the separator it guesses).
  std::string head;
  if (!s.file->ok() || !s.file->read(0, std::min(s.size, kMostHeaderBytes), head)) return "cannot read the file";
  const std::size_t lf = head.find('\n');
  if (lf == std::string::npos) return "no line after the header";
  s.header = head.substr(0, lf + 1);
  if (std::count(s.header.begin(), s.header.end(), '"') % 2 != 0) return "a quoted header that goes on past its line";
  s.data_start = lf + 1;
  const std::size_t data = s.size - s.data_start;
  // QTMV_READ_RANGE_BYTES: the tests' small ranges (a value that is not a positive number: the default).
  const char* const asked = config_option("QTMV_READ_RANGE_BYTES");
  char* asked_end = nullptr;
  const unsigned long long range_bytes = asked ? std::strtoull(asked, &asked_end, 10) : 0;
  s.range_bytes = range_bytes > 0 && *asked_end == '\0'
                      ? static_cast<std::size_t>(range_bytes)
                      : std::clamp(data / (static_cast<std::size_t>(readers) * kRangesPerThread), kMinRangeBytes,
                                   kMaxRangeBytes);
  s.ranges = (data + s.range_bytes - 1) / s.range_bytes;
  if (s.ranges < 2) return "one range of " + std::to_string(data) + " bytes";
  for (const char* extension : {"csvt", "prj"}) {
    std::string bytes;
    if (read_sidecar(CPLResetExtension(source.name.c_str(), extension), bytes)) s.sidecars.emplace_back(extension, std::move(bytes));
  }
  if (std::string why = scan_data(source.name, s.data_start, s.size, threads); !why.empty()) return why;
  s.open_options = options.open_options;
  s.where = options.where;
  s.folder = "/vsimem/qtmv_split_read_" + std::to_string(split_reads.fetch_add(1)) + "_" + std::to_string(::getpid());
  return {};
}

/// Why a part of the header alone does not read as the layer (no feature, the same fields,
/// geometry fields and CRS): the first line is not a header, or a sidecar is not found; empty
/// when it does.
std::string header_refusal(OGRLayer& layer, const SplitRead::Impl& s) {
  const MemoryCsv csv(s.folder + "/probe/" + s.file_name, s.header, s.sidecars);
  const gdal::ErrorCapture quiet;
  const GDALDatasetUniquePtr dataset = csv.open(s.open_options);
  OGRLayer* const probe = dataset && dataset->GetLayerCount() == 1 ? dataset->GetLayer(0) : nullptr;
  const OGRSpatialReference *a = probe ? probe->GetSpatialRef() : nullptr, *b = layer.GetSpatialRef();
  if (!probe) return "the header line alone does not open";
  if (OGRFeatureUniquePtr(probe->GetNextFeature())) return "the first line is data, not a header";
  if (!probe->GetLayerDefn()->IsSame(layer.GetLayerDefn()) || (a == nullptr) != (b == nullptr) || (a && !a->IsSame(b))) {
    return "the header line alone reads with other fields or CRS";
  }
  return {};
}

}  // namespace

std::unique_ptr<SplitRead> SplitRead::open(const OgrSource& source, std::size_t layer_number,
                                           const ReadOptions& options, int threads, const std::string& where_from) {
  auto s = std::make_unique<Impl>();
  OGRLayer& layer = *source.layers[layer_number].layer;
  const int readers = static_cast<int>(std::min(static_cast<std::size_t>(std::max(threads, 0)), kMostReaders));
  std::string why = split_refusal(source, layer, options, threads, readers, *s);
  if (why.empty() && !s->by_fid) why = header_refusal(layer, *s);
  if (!why.empty()) {
    trace_printf(TraceStage::read, "%s: read on one thread: %s", where_from.c_str(), why.c_str());
    return nullptr;
  }
  // A part's thread for each of the run's threads, up to kMostReaders: the reading thread mostly
  // waits for them (on 2 cores, 1M points: whole read 1.36 s, against 1.85 s with one part's
  // thread fewer).
  const std::size_t reader_threads = std::min(static_cast<std::size_t>(readers), s->ranges);
  if (s->by_fid) {
    trace_printf(TraceStage::read, "%s: split read: %zu ranges of %lld FIDs, read by %zu threads", where_from.c_str(),
                 s->ranges, static_cast<long long>(s->fid_step), reader_threads);
  } else {
    trace_printf(TraceStage::read, "%s: split read: %zu ranges of about %zu bytes, read by %zu threads",
                 where_from.c_str(), s->ranges, s->range_bytes, reader_threads);
  }
  s->parts.resize(s->ranges);
  s->window = 2 * reader_threads + 2;
  Impl* const impl = s.get();
  std::unique_ptr<SplitRead> split(new SplitRead(std::move(s)));
  for (std::size_t t = 0; t < reader_threads; ++t) impl->threads.emplace_back([impl] { impl->work(); });
  return split;
}

SplitRead::SplitRead(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

SplitRead::~SplitRead() {
  {
    const std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->stop = true;
  }
  impl_->room.notify_all();
  for (std::thread& t : impl_->threads) t.join();
}

OGRFeatureUniquePtr SplitRead::next() {
  Impl& s = *impl_;
  for (;;) {
    if (s.current) {
      Part& part = *s.current;
      std::size_t m = 0;
      bool failed = false;
      for (; m < part.messages.size() && part.messages[m].at <= s.position; ++m) {
        s.raise(part.messages[m]);
        failed |= part.messages[m].type >= CE_Failure && part.messages[m].at == part.features.size();
      }
      part.messages.erase(part.messages.begin(), part.messages.begin() + static_cast<std::ptrdiff_t>(m));
      if (s.position < part.features.size()) {
        OGRFeatureUniquePtr feature = std::move(part.features[s.position++]);
        feature->SetFID(feature->GetFID() + s.fid_shift);
        return feature;
      }
      // A part whose read failed ends the read there, as the sequential read would have ended.
      s.ended = failed;
      s.fid_shift += part.records;
      s.current.reset();
    }
    if (s.ended || s.handed == s.ranges) return nullptr;
    {
      std::unique_lock<std::mutex> lock(s.mutex);
      s.part_ready.wait(lock, [&] { return s.parts[s.handed] != nullptr; });
      s.current = std::move(s.parts[s.handed]);
      s.consumed = ++s.handed;
      s.position = 0;
    }
    s.room.notify_all();
  }
}

double SplitRead::fraction_done() const {
  const Impl& s = *impl_;
  if (s.ranges == 0) return 1.0;
  double in_current = 0.0;
  if (s.current && !s.current->features.empty()) {
    in_current = static_cast<double>(s.position) / static_cast<double>(s.current->features.size());
  }
  return std::min(1.0, (static_cast<double>(s.handed) - (s.current ? 1.0 - in_current : 0.0)) / static_cast<double>(s.ranges));
}

}  // namespace qtmv::sites
