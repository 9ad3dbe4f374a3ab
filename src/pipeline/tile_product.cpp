#include "pipeline/tile_product.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "common/run_context.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {

namespace {

constexpr char kMagic[8] = {'Q', 'T', 'M', 'V', 'T', 'I', 'L', 'E'};
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kHeaderBytes = 88;
constexpr std::size_t kCellBytes = 12;
constexpr std::size_t kSiteKeyBytes = 16;

static_assert(sizeof(label::OutlineCell) == kCellBytes, "outline cells are written as they are held");

/// Word-wise hash: each step (xor, then multiply by an odd constant) is a bijection of the state,
/// so one changed word always changes the result; a final mix spreads it over all bits.
class Hash64 {
 public:
  void add(std::uint64_t word) { state_ = (state_ ^ word) * 0x100000001b3ull + 0x9e3779b97f4a7c15ull; }
  void add_double(double value) {
    std::uint64_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    add(bits);
  }
  void add_bytes(const unsigned char* data, std::size_t size) {
    std::size_t k = 0;
    for (; k + 8 <= size; k += 8) {
      std::uint64_t word;
      std::memcpy(&word, data + k, 8);
      add(word);
    }
    std::uint64_t tail = 0;
    std::memcpy(&tail, data + k, size - k);
    add(tail ^ (std::uint64_t{size - k} << 56));
  }
  std::uint64_t value() const {
    std::uint64_t h = state_;
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    h *= 0xc4ceb9fe1a85ec53ull;
    return h ^ (h >> 33);
  }

 private:
  std::uint64_t state_ = 0xcbf29ce484222325ull;
};

template <class T>
void put(std::vector<unsigned char>& out, T value) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(&value);
  out.insert(out.end(), bytes, bytes + sizeof value);
}

template <class T>
T get(const unsigned char* data, std::size_t& at) {
  T value;
  std::memcpy(&value, data + at, sizeof value);
  at += sizeof value;
  return value;
}

struct FileCloser {
  void operator()(VSILFILE* f) const { VSIFCloseL(f); }
};
using File = std::unique_ptr<VSILFILE, FileCloser>;

/// GDAL's messages, if any, for the end of a message.
std::string said(gdal::ErrorCapture& errors) {
  const std::string text = errors.take();
  return text.empty() ? "" : " (GDAL: " + text + ")";
}

std::string rule_name(label::Rule rule) { return rule == label::Rule::exact ? "exact" : "cell"; }

}  // namespace

std::vector<std::uint64_t> site_fingerprints(const label::LabelInput& in) {
  // Each site's pieces in array order: a site's pieces are made from its feature alone, so they
  // are the same whichever other sites are read with it.
  std::vector<Hash64> per_site(static_cast<std::size_t>(std::max(in.site_count, 0)));
  for (std::size_t k = 0; k < in.piece_count; ++k) {
    const label::SitePiece& p = in.pieces[k];
    if (p.site < 0 || p.site >= in.site_count) continue;
    Hash64& h = per_site[static_cast<std::size_t>(p.site)];
    for (const double v : {p.a.x, p.a.y, p.a.z, p.b.x, p.b.y, p.b.z}) h.add_double(v);
  }
  std::vector<std::uint64_t> out(per_site.size());
  for (std::size_t s = 0; s < out.size(); ++s) out[s] = per_site[s].value();
  return out;
}

std::uint64_t sites_fingerprint(const std::vector<std::uint64_t>& per_site, const std::vector<std::int32_t>* ids) {
  Hash64 h;
  const std::size_t n = ids ? ids->size() : per_site.size();
  h.add(n);
  for (std::size_t k = 0; k < n; ++k) h.add(per_site[ids ? static_cast<std::size_t>((*ids)[k]) : k]);
  return h.value();
}

std::uint64_t reading_fingerprint(const sites::SourceOptions& o) {
  Hash64 h;
  const auto add = [&h](const std::string& text) {
    h.add_bytes(reinterpret_cast<const unsigned char*>(text.data()), text.size());
  };
  h.add(o.layers.size());
  for (const std::string& layer : o.layers) add(layer);
  for (const std::string& text : {o.where, o.sql, o.dialect, o.source_srs}) add(text);
  h.add(o.open_options.size());
  for (const std::string& option : o.open_options) add(option);
  h.add(static_cast<std::uint64_t>(o.edges) << 16 | static_cast<std::uint64_t>(o.wrap) << 8 |
        static_cast<std::uint64_t>(o.strict) << 1 | static_cast<std::uint64_t>(o.make_valid));
  return h.value();
}

void write_tile_product(const std::string& path, const TileProduct& product) {
  const label::Outlines& o = product.outlines;
  if (!product.sites.empty() && product.sites.size() != static_cast<std::size_t>(o.site_count)) {
    throw std::logic_error("a tile product lists all its sites or none");
  }
  std::vector<unsigned char> listed;
  listed.reserve(product.sites.size() * kSiteKeyBytes);
  for (const SiteKey& key : product.sites) {
    put<std::int64_t>(listed, key.fid);
    put<std::uint32_t>(listed, key.layer);
    put<std::uint32_t>(listed, 0u);
  }
  std::vector<unsigned char> header;
  header.insert(header.end(), kMagic, kMagic + sizeof kMagic);
  put<std::uint32_t>(header, kVersion);
  put<std::uint32_t>(header, static_cast<std::uint32_t>(o.level));
  put<std::uint32_t>(header, product.rule == label::Rule::exact ? 0u : 1u);
  put<std::uint32_t>(header, static_cast<std::uint32_t>(product.index));
  put<std::uint32_t>(header, static_cast<std::uint32_t>(product.count));
  put<std::int32_t>(header, o.site_count);
  put<std::uint64_t>(header, product.sites_fingerprint);
  put<std::uint64_t>(header, o.range.first);
  put<std::uint64_t>(header, o.range.end);
  put<std::uint64_t>(header, o.cells.size());
  put<std::uint64_t>(header, product.sites.size());
  put<std::uint64_t>(header, product.sites.empty() ? 0 : product.source_features);
  put<std::uint64_t>(header, product.sites.empty() ? 0 : product.reading);
  if (header.size() != kHeaderBytes) throw std::logic_error("tile product header size");

  gdal::ErrorCapture errors;
  File file(VSIFOpenL(path.c_str(), "wb"));
  if (!file) throw VoronoiError("'" + path + "': cannot create the tile product" + said(errors));
  Hash64 checksum;
  bool ok = true;
  const auto write = [&](const void* data, std::size_t size) {
    if (size == 0 || !ok) return;
    checksum.add_bytes(static_cast<const unsigned char*>(data), size);
    ok = VSIFWriteL(data, 1, size, file.get()) == size;
  };
  write(header.data(), header.size());
  write(listed.data(), listed.size());
  // Checksummed in the chunks it is written in, as the reader reads them.
  write(o.cells.data(), o.cells.size() * kCellBytes);
  write(o.cells_per_site.data(), o.cells_per_site.size() * sizeof(std::uint64_t));
  const std::uint64_t sum = checksum.value();
  ok = ok && VSIFWriteL(&sum, 1, sizeof sum, file.get()) == sizeof sum;
  ok = VSIFCloseL(file.release()) == 0 && ok;
  if (!ok) throw VoronoiError("'" + path + "': writing the tile product failed (disk full?)" + said(errors));
}

namespace {

/// A tile product whose header has been read and checked; read_body() reads the rest. The file
/// is open only while each is read (a merge may hold thousands of these).
class TileReader {
 public:
  explicit TileReader(std::string path) : path_(std::move(path)) {
    gdal::ErrorCapture errors;
    VSIStatBufL stat;
    if (VSIStatL(path_.c_str(), &stat) != 0) throw fail("no such tile product");
    const File file(VSIFOpenL(path_.c_str(), "rb"));
    if (!file) throw fail("cannot open the tile product" + said(errors));
    const auto size = static_cast<std::uint64_t>(stat.st_size);
    // The magic and version first: a version 1 product is shorter than this version's header.
    constexpr std::size_t kLead = sizeof kMagic + sizeof(std::uint32_t);
    if (size < kLead || VSIFReadL(header_, 1, kLead, file.get()) != kLead || std::memcmp(header_, kMagic, sizeof kMagic) != 0) {
      throw fail("not a qtmvoronoi tile product (made by qtmvoronoi -tile K/N)");
    }
    std::size_t at = sizeof kMagic;
    const auto version = get<std::uint32_t>(header_, at);
    if (version != kVersion) {
      // Version 1 named no sites: its fingerprint was of the whole input, which this version
      // does not compute.
      throw fail("a tile product of version " + std::to_string(version) + "; this qtmvoronoi reads version " +
                 std::to_string(kVersion) + ": run the tile jobs again with this version");
    }
    if (size < kHeaderBytes || VSIFReadL(header_ + kLead, 1, kHeaderBytes - kLead, file.get()) != kHeaderBytes - kLead) {
      throw fail("truncated tile product (its header is cut short)");
    }
    level = static_cast<int>(get<std::uint32_t>(header_, at));
    const auto rule_code = get<std::uint32_t>(header_, at);
    index = static_cast<int>(get<std::uint32_t>(header_, at));
    count = static_cast<int>(get<std::uint32_t>(header_, at));
    site_count = get<std::int32_t>(header_, at);
    sites_fingerprint = get<std::uint64_t>(header_, at);
    range.first = get<std::uint64_t>(header_, at);
    range.end = get<std::uint64_t>(header_, at);
    cells = get<std::uint64_t>(header_, at);
    const auto listed = get<std::uint64_t>(header_, at);
    source_features = get<std::uint64_t>(header_, at);
    reading = get<std::uint64_t>(header_, at);
    if (!grid::is_valid_level(level) || rule_code > 1 || site_count <= 0 || count < 1 || index < 1 || index > count ||
        (listed != 0 && listed != static_cast<std::uint64_t>(site_count)) ||
        count > grid::most_row_parts(level) || cells > grid::cell_count(level) ||
        !(range == grid::tile_range(level, index, count))) {
      throw fail("corrupt tile product (its header holds impossible values)");
    }
    rule = rule_code == 0 ? label::Rule::exact : label::Rule::cell;
    const std::uint64_t expected = kHeaderBytes + listed * kSiteKeyBytes + cells * kCellBytes +
                                   static_cast<std::uint64_t>(site_count) * sizeof(std::uint64_t) + sizeof(std::uint64_t);
    if (size < expected) {
      throw fail("truncated tile product (" + std::to_string(size) + " bytes of " + std::to_string(expected) +
                 "): was its tile job stopped, or the copy cut short?");
    }
    if (size > expected) throw fail("corrupt tile product (" + std::to_string(size - expected) + " bytes too many)");
    listed_bytes_.resize(listed * kSiteKeyBytes);
    if (!listed_bytes_.empty() && VSIFReadL(listed_bytes_.data(), 1, listed_bytes_.size(), file.get()) != listed_bytes_.size()) {
      throw fail("reading failed" + said(errors));
    }
    sites.resize(listed);
    std::size_t k = 0;
    for (SiteKey& key : sites) {
      key.fid = get<std::int64_t>(listed_bytes_.data(), k);
      key.layer = get<std::uint32_t>(listed_bytes_.data(), k);
      k += sizeof(std::uint32_t);
    }
  }

  /// Reads the outline cells into out[0, cells) and the cells per site into *counts (the tile's
  /// sites), checking the checksum and that the cells lie in the tile's codes in order; the tile's
  /// site s is the merge's site whole_id[s] (all the tile's sites; empty: the same ids). The
  /// caller checks the whole level's cells (check_outlines). Any thread.
  void read_body(label::OutlineCell* out, std::vector<std::uint64_t>* counts, const std::vector<std::int32_t>& whole_id) {
    gdal::ErrorCapture errors;
    const File file(VSIFOpenL(path_.c_str(), "rb"));
    if (!file || VSIFSeekL(file.get(), kHeaderBytes + listed_bytes_.size(), SEEK_SET) != 0) {
      throw fail("cannot open the tile product" + said(errors));
    }
    Hash64 checksum;
    checksum.add_bytes(header_, kHeaderBytes);
    if (!listed_bytes_.empty()) checksum.add_bytes(listed_bytes_.data(), listed_bytes_.size());
    counts->assign(static_cast<std::size_t>(site_count), 0);
    std::uint64_t stored = 0;
    const auto read = [&](void* data, std::size_t bytes) {
      if (bytes > 0 && VSIFReadL(data, 1, bytes, file.get()) != bytes) throw fail("reading failed" + said(errors));
    };
    read(out, cells * kCellBytes);
    checksum.add_bytes(reinterpret_cast<const unsigned char*>(out), cells * kCellBytes);
    read(counts->data(), counts->size() * sizeof(std::uint64_t));
    checksum.add_bytes(reinterpret_cast<const unsigned char*>(counts->data()), counts->size() * sizeof(std::uint64_t));
    read(&stored, sizeof stored);
    if (stored != checksum.value()) throw fail("corrupt tile product (its checksum does not match its contents)");
    for (std::size_t k = 0; k < cells; ++k) {
      label::OutlineCell& cell = out[k];
      const grid::Code code = cell.code();
      if (code < range.first || code >= range.end || (k > 0 && out[k - 1].code() >= code)) {
        throw fail("corrupt tile product (outline cell " + std::to_string(code) + " out of place)");
      }
      if (whole_id.empty()) continue;
      if (cell.site < 0 || cell.site >= site_count) throw fail("corrupt tile product (a cell of site " + std::to_string(cell.site) + ")");
      cell.site = whole_id[static_cast<std::size_t>(cell.site)];
    }
  }

  VoronoiError fail(const std::string& why) const { return VoronoiError("'" + path_ + "': " + why); }
  const std::string& path() const { return path_; }

  int level = 0, index = 0, count = 0;
  label::Rule rule = label::Rule::exact;
  std::int32_t site_count = 0;
  std::uint64_t sites_fingerprint = 0, cells = 0, source_features = 0, reading = 0;
  grid::CodeRange range;
  std::vector<SiteKey> sites;  ///< the sites listed (empty: the whole source's)

 private:
  std::string path_;
  unsigned char header_[kHeaderBytes];
  std::vector<unsigned char> listed_bytes_;
};

}  // namespace

namespace {

/// Refuses a tile product that is not a regular file: a FIFO would block the merge for ever.
void check_regular_file(const std::string& path, const VSIStatBufL& stat) {
  if (VSI_ISREG(stat.st_mode)) return;
  throw VoronoiError("-merge: '" + path + "': not a regular file (" +
                     special_file_kind(static_cast<unsigned>(stat.st_mode)) +
                     "); -merge takes the files that -tile runs wrote");
}

}  // namespace

MissingTiles missing_tiles(int count, const std::function<bool(int)>& present) {
  MissingTiles out;
  int listed = 0;
  for (int k = 1; k <= count; ++k) {
    if (present(k)) continue;
    ++out.count;
    if (listed < 20) out.list += (listed++ ? ", " : "") + std::to_string(k);
  }
  if (out.count > listed) out.list += ", ...";
  return out;
}

std::vector<std::string> merge_input_files(const std::vector<std::string>& paths,
                                           const std::vector<std::string>& extensions, const std::string& none_found) {
  std::vector<std::string> files;
  for (const std::string& path : paths) {
    VSIStatBufL stat;
    if (VSIStatL(path.c_str(), &stat) != 0) throw VoronoiError("-merge: '" + path + "': no such file or directory");
    if (!VSI_ISDIR(stat.st_mode)) {
      check_regular_file(path, stat);
      files.push_back(path);
      continue;
    }
    char** names = VSIReadDir(path.c_str());
    std::vector<std::string> found;
    for (char** n = names; n && *n; ++n) {
      const std::string name = *n;
      for (const std::string& extension : extensions) {
        if (name.size() > extension.size() &&
            name.compare(name.size() - extension.size(), extension.size(), extension) == 0) {
          found.push_back(CPLFormFilename(path.c_str(), name.c_str(), nullptr));
          break;
        }
      }
    }
    CSLDestroy(names);
    if (found.empty()) throw VoronoiError("-merge: '" + path + "': " + none_found);
    std::sort(found.begin(), found.end());
    for (const std::string& file : found) {
      if (VSIStatL(file.c_str(), &stat) != 0) throw VoronoiError("-merge: '" + file + "': no such file");
      check_regular_file(file, stat);
    }
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

namespace {

/// The merge's sites by layer and FID: where a tile's listed sites are.
class WholeSites {
 public:
  explicit WholeSites(const MergeExpectation& expect) : expect_(expect) {}

  /// The merge's id of each of the tile's sites (empty when it lists none: they must then be the
  /// merge's, which the fingerprint checks). Throws VoronoiError for a site the merge has not, or
  /// sites in another order than the merge's.
  std::vector<std::int32_t> ids_of(const TileReader& tile) const {
    std::vector<std::int32_t> ids;
    if (tile.sites.empty()) return ids;
    // The sites it did not read are not named: the same source read the same way has them.
    if (tile.reading != expect_.reading || tile.source_features != expect_.source_features) {
      throw tile.fail("a tile of other sites than " + expect_.source + " read with these options (" +
                      std::to_string(tile.source_features) + " features, against " +
                      std::to_string(expect_.source_features) + " read now" +
                      (tile.reading != expect_.reading ? ", with other reading options" : "") +
                      "): give the merge the source and the reading options (-l, -where, -s_srs, -oo, -edges, "
                      "-wrap, ...) of the tile jobs");
    }
    sort_once();
    ids.reserve(tile.sites.size());
    for (const SiteKey& key : tile.sites) {
      const auto found = std::lower_bound(by_key_.begin(), by_key_.end(), std::make_pair(key, std::int32_t{-1}),
                                          [](const auto& a, const auto& b) { return a.first < b.first; });
      if (found == by_key_.end() || found->first < key || key < found->first) {
        throw tile.fail("a tile of other sites than " + expect_.source + " read with these options (its site FID " +
                        std::to_string(key.fid) + " of layer " + std::to_string(key.layer + 1) +
                        " is not among them): give the merge the source and the reading options of the tile jobs");
      }
      if (duplicated_) {
        throw tile.fail("its sites are named by their FIDs, but " + expect_.source +
                        " has several sites with one FID: run the tile jobs with --config QTMV_TILE_SITES ALL");
      }
      if (!ids.empty() && found->second <= ids.back()) {
        throw tile.fail("its sites were read in another order than " + expect_.source +
                        " gives them now (not by FID): run the tile jobs with --config QTMV_TILE_SITES ALL");
      }
      ids.push_back(found->second);
    }
    return ids;
  }

 private:
  void sort_once() const {
    if (sorted_) return;
    sorted_ = true;
    by_key_.reserve(expect_.site_keys.size());
    for (std::size_t s = 0; s < expect_.site_keys.size(); ++s) by_key_.emplace_back(expect_.site_keys[s], static_cast<std::int32_t>(s));
    std::sort(by_key_.begin(), by_key_.end());
    for (std::size_t k = 1; k < by_key_.size(); ++k) {
      if (!(by_key_[k - 1].first < by_key_[k].first)) duplicated_ = true;
    }
  }

  const MergeExpectation& expect_;
  mutable bool sorted_ = false, duplicated_ = false;
  mutable std::vector<std::pair<SiteKey, std::int32_t>> by_key_;
};

}  // namespace

std::vector<std::string> tile_product_files(const std::vector<std::string>& paths) {
  return merge_input_files(paths, {kTileProductExtension},
                           std::string("a directory without ") + kTileProductExtension + " files");
}

label::Outlines merge_tile_products(const std::vector<std::string>& files, const MergeExpectation& expect,
                                    const std::function<bool(double)>& progress) {
  if (files.empty()) throw VoronoiError("-merge: no tile products given");
  // Every header first: a tile that does not belong, or one missing, fails before the reading.
  std::map<int, std::unique_ptr<TileReader>> tiles;  // by index
  std::map<int, std::vector<std::int32_t>> whole_ids;  // of the tiles that list their sites
  const WholeSites whole(expect);
  int count = 0;
  std::string count_from;
  for (const std::string& file : files) {
    auto tile = std::make_unique<TileReader>(file);
    if (tile->level != expect.level) {
      throw tile->fail("a tile of level " + std::to_string(tile->level) + "; this merge is of level " +
                       std::to_string(expect.level) + " (-level)");
    }
    if (tile->rule != expect.rule) {
      throw tile->fail("a tile labelled with -distance " + rule_name(tile->rule) + "; this merge uses -distance " +
                       rule_name(expect.rule));
    }
    std::vector<std::int32_t> ids = whole.ids_of(*tile);
    if ((tile->sites.empty() && tile->site_count != expect.site_count) ||
        tile->sites_fingerprint != sites_fingerprint(expect.site_fingerprints, tile->sites.empty() ? nullptr : &ids)) {
      throw tile->fail("a tile of other sites than " + expect.source + " read with these options (" +
                       std::to_string(tile->site_count) + " sites, against " + std::to_string(expect.site_count) +
                       " read now): give the merge the source and the reading options (-l, -where, -sql, -s_srs, "
                       "-oo, -edges, ...) of the tile jobs");
    }
    if (count == 0) {
      count = tile->count;
      count_from = file;
    } else if (tile->count != count) {
      throw tile->fail("tile " + std::to_string(tile->index) + " of " + std::to_string(tile->count) + ", but '" +
                       count_from + "' is a tile of " + std::to_string(count) +
                       ": all tiles of a merge come from one split -tile K/N");
    }
    const int index = tile->index;
    if (const auto same = tiles.find(index); same != tiles.end()) {
      throw tile->fail("tile " + std::to_string(index) + "/" + std::to_string(count) + " again; '" +
                       same->second->path() + "' is that tile too");
    }
    whole_ids.emplace(index, std::move(ids));
    tiles.emplace(index, std::move(tile));
  }
  if (static_cast<int>(tiles.size()) != count) {
    const MissingTiles missing = missing_tiles(count, [&](int k) { return tiles.count(k) > 0; });
    throw VoronoiError("-merge: " + std::to_string(missing.count) + " of the " + std::to_string(count) +
                       " tiles missing (" + missing.list + ")");
  }
  // Then the bodies, each straight into its place in the level's list (the tiles in code order):
  // the outline cells are held once, as a whole run holds them. A tile a thread (gigabytes at the
  // finer levels), while the calling thread reports the progress. A failed tile stops the tiles
  // after it, not those before: the error is the first bad tile's, as reading them in order gives.
  label::Outlines joined;
  joined.level = expect.level;
  joined.site_count = expect.site_count;
  joined.range = grid::whole_level(expect.level);
  joined.cells_per_site.assign(static_cast<std::size_t>(expect.site_count), 0);
  std::vector<TileReader*> order;
  std::vector<const std::vector<std::int32_t>*> ids;  // each tile's whole_ids (no map lookups on the threads)
  std::vector<std::size_t> first;  // each tile's first cell in joined.cells
  std::size_t cells = 0;
  for (const auto& [index, tile] : tiles) {
    order.push_back(tile.get());
    ids.push_back(&whole_ids.at(index));
    first.push_back(cells);
    cells += tile->cells;
  }
  joined.cells.resize(cells);  // not zeroed (default-initialised), filled by the tiles' threads
  const std::size_t n = order.size();
  std::vector<std::exception_ptr> failed(n);
  std::atomic<std::size_t> next{0}, done{0}, first_failed{n};
  std::atomic<int> readers_left{0};
  std::atomic<bool> stop{false};
  std::exception_ptr progress_failed;
  std::mutex counts_lock;
  const auto read_tile = [&](std::size_t t) {
    try {
      std::vector<std::uint64_t> counts;
      order[t]->read_body(joined.cells.data() + first[t], &counts, *ids[t]);
      const std::vector<std::int32_t>& id = *ids[t];
      const std::lock_guard<std::mutex> hold(counts_lock);  // integer sums: the same in any order
      for (std::size_t s = 0; s < counts.size(); ++s) joined.cells_per_site[id.empty() ? s : static_cast<std::size_t>(id[s])] += counts[s];
    } catch (...) {
      failed[t] = std::current_exception();
      for (std::size_t at = first_failed.load(); t < at && !first_failed.compare_exchange_weak(at, t);) {
      }
    }
    done.fetch_add(1);
  };
  const auto report = [&] {
    if (!progress || stop.load()) return;
    try {
      if (!progress(double(done.load()) / double(n))) stop = true;
    } catch (...) {
      progress_failed = std::current_exception();
      stop = true;
    }
  };
  // Reads the next tile not taken yet, unless stopped or a tile before it failed; false once none is left.
  const auto read_next = [&] {
    const std::size_t t = next.fetch_add(1);
    if (t >= n || stop.load() || t >= first_failed.load()) return false;
    read_tile(t);
    return true;
  };
  const int readers = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(thread_count(0)), n));
  if (readers <= 1) {
    while (read_next()) report();
  } else {
    readers_left = readers;
#pragma omp parallel num_threads(readers + 1)
    {
      if (thread_index() == 0) {
        for (std::size_t reported = n + 1;;) {
          const bool last = readers_left.load() == 0;
          if (done.load() != reported) {
            reported = done.load();
            report();
          }
          if (last) break;
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
      } else {
        while (read_next()) {
        }
        readers_left.fetch_sub(1);
      }
    }
  }
  if (first_failed.load() < n) std::rethrow_exception(failed[first_failed.load()]);
  if (progress_failed) std::rethrow_exception(progress_failed);
  if (stop) throw Interrupted();
  tiles.clear();
  whole_ids.clear();
  try {
    label::check_outlines(joined);
  } catch (const std::exception& e) {
    throw VoronoiError(std::string("-merge: the tile products do not make the level's outline cells (") + e.what() + ")");
  }
  return joined;
}

}  // namespace qtmv::pipeline
