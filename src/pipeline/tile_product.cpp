#include "pipeline/tile_product.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>

#include "common/host_info.hpp"
#include "common/run_context.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {

namespace {

constexpr char kMagic[8] = {'Q', 'T', 'M', 'V', 'T', 'I', 'L', 'E'};
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kHeaderBytes = 64;
constexpr std::size_t kCellBytes = 12;

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

std::uint64_t input_fingerprint(const label::LabelInput& in) {
  Hash64 h;
  h.add(static_cast<std::uint64_t>(in.level));
  h.add(static_cast<std::uint64_t>(in.site_count));
  h.add(in.piece_count);
  for (std::size_t k = 0; k < in.piece_count; ++k) {
    const label::SitePiece& p = in.pieces[k];
    for (const double v : {p.a.x, p.a.y, p.a.z, p.b.x, p.b.y, p.b.z}) h.add_double(v);
    h.add(static_cast<std::uint64_t>(p.site));
  }
  h.add(in.site_cell_count);
  for (std::size_t k = 0; k < in.site_cell_count; ++k) {
    const label::SiteCell& c = in.site_cells[k];
    h.add(c.code);
    h.add(static_cast<std::uint64_t>(c.site));
  }
  h.add(in.fixed_cell_count);
  for (std::size_t k = 0; k < in.fixed_cell_count; ++k) {
    h.add(in.fixed_cells[k].code);
    h.add(static_cast<std::uint64_t>(in.fixed_cells[k].site));
  }
  h.add(in.fixed_node_count);
  for (std::size_t k = 0; k < in.fixed_node_count; ++k) {
    const label::FixedNode& n = in.fixed_nodes[k];
    h.add(n.code);
    h.add(static_cast<std::uint64_t>(n.level) << 32 | static_cast<std::uint32_t>(n.site));
  }
  return h.value();
}

void write_tile_product(const std::string& path, const TileProduct& product) {
  const label::Outlines& o = product.outlines;
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
    if (size < kHeaderBytes || VSIFReadL(header_, 1, kHeaderBytes, file.get()) != kHeaderBytes ||
        std::memcmp(header_, kMagic, sizeof kMagic) != 0) {
      throw fail("not a qtmvoronoi tile product (made by qtmvoronoi -tile K/N)");
    }
    std::size_t at = sizeof kMagic;
    const auto version = get<std::uint32_t>(header_, at);
    if (version != kVersion) {
      throw fail("a tile product of version " + std::to_string(version) + "; this qtmvoronoi reads version " +
                 std::to_string(kVersion) + ": run the tile jobs again with this version");
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
    if (!grid::is_valid_level(level) || rule_code > 1 || site_count <= 0 || count < 1 || index < 1 || index > count ||
        count > grid::most_row_parts(level) || cells > grid::cell_count(level) ||
        !(range == grid::tile_range(level, index, count))) {
      throw fail("corrupt tile product (its header holds impossible values)");
    }
    rule = rule_code == 0 ? label::Rule::exact : label::Rule::cell;
    const std::uint64_t expected = kHeaderBytes + cells * kCellBytes +
                                   static_cast<std::uint64_t>(site_count) * sizeof(std::uint64_t) + sizeof(std::uint64_t);
    if (size < expected) {
      throw fail("truncated tile product (" + std::to_string(size) + " bytes of " + std::to_string(expected) +
                 "): was its tile job stopped, or the copy cut short?");
    }
    if (size > expected) throw fail("corrupt tile product (" + std::to_string(size - expected) + " bytes too many)");
  }

  /// Appends the outline cells to *cells and adds the cells per site to *per_site (site_count of
  /// them), checking the checksum. The caller checks the cells (check_outlines).
  void read_body(label::OutlineCells* out, std::vector<std::uint64_t>* per_site) {
    gdal::ErrorCapture errors;
    const File file(VSIFOpenL(path_.c_str(), "rb"));
    if (!file || VSIFSeekL(file.get(), kHeaderBytes, SEEK_SET) != 0) throw fail("cannot open the tile product" + said(errors));
    Hash64 checksum;
    checksum.add_bytes(header_, kHeaderBytes);
    const std::size_t at = out->size();
    out->resize(at + cells);
    std::vector<std::uint64_t> counts(static_cast<std::size_t>(site_count));
    std::uint64_t stored = 0;
    const auto read = [&](void* data, std::size_t bytes) {
      if (bytes > 0 && VSIFReadL(data, 1, bytes, file.get()) != bytes) throw fail("reading failed" + said(errors));
    };
    read(out->data() + at, cells * kCellBytes);
    checksum.add_bytes(reinterpret_cast<const unsigned char*>(out->data() + at), cells * kCellBytes);
    read(counts.data(), counts.size() * sizeof(std::uint64_t));
    checksum.add_bytes(reinterpret_cast<const unsigned char*>(counts.data()), counts.size() * sizeof(std::uint64_t));
    read(&stored, sizeof stored);
    if (stored != checksum.value()) throw fail("corrupt tile product (its checksum does not match its contents)");
    per_site->resize(counts.size(), 0);
    for (std::size_t s = 0; s < counts.size(); ++s) (*per_site)[s] += counts[s];
  }

  VoronoiError fail(const std::string& why) const { return VoronoiError("'" + path_ + "': " + why); }
  const std::string& path() const { return path_; }

  int level = 0, index = 0, count = 0;
  label::Rule rule = label::Rule::exact;
  std::int32_t site_count = 0;
  std::uint64_t sites_fingerprint = 0, cells = 0;
  grid::CodeRange range;

 private:
  std::string path_;
  unsigned char header_[kHeaderBytes];
};

}  // namespace

namespace {

/// Refuses a tile product that is not a regular file: a FIFO would block the merge for ever.
void check_regular_file(const std::string& path, const VSIStatBufL& stat) {
  if (VSI_ISREG(stat.st_mode)) return;
  throw VoronoiError("-merge: '" + path + "': not a regular file (" +
                     special_file_kind(static_cast<unsigned>(stat.st_mode)) +
                     "); a tile product is a file that a -tile run wrote");
}

}  // namespace

std::vector<std::string> tile_product_files(const std::vector<std::string>& paths) {
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
      const std::string extension = kTileProductExtension;
      if (name.size() > extension.size() && name.compare(name.size() - extension.size(), extension.size(), extension) == 0) {
        found.push_back(CPLFormFilename(path.c_str(), name.c_str(), nullptr));
      }
    }
    CSLDestroy(names);
    if (found.empty()) throw VoronoiError("-merge: '" + path + "': a directory without " + kTileProductExtension + " files");
    std::sort(found.begin(), found.end());
    for (const std::string& file : found) {
      if (VSIStatL(file.c_str(), &stat) != 0) throw VoronoiError("-merge: '" + file + "': no such file");
      check_regular_file(file, stat);
    }
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

label::Outlines merge_tile_products(const std::vector<std::string>& files, const MergeExpectation& expect,
                                    const std::function<bool(double)>& progress) {
  if (files.empty()) throw VoronoiError("-merge: no tile products given");
  // Every header first: a tile that does not belong, or one missing, fails before the reading.
  std::map<int, std::unique_ptr<TileReader>> tiles;  // by index
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
    if (tile->site_count != expect.site_count || tile->sites_fingerprint != expect.sites_fingerprint) {
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
    tiles.emplace(index, std::move(tile));
  }
  if (static_cast<int>(tiles.size()) != count) {
    std::string missing;
    int listed = 0, absent = 0;
    for (int k = 1; k <= count; ++k) {
      if (tiles.count(k)) continue;
      ++absent;
      if (listed < 20) missing += (listed++ ? ", " : "") + std::to_string(k);
    }
    throw VoronoiError("-merge: " + std::to_string(absent) + " of the " + std::to_string(count) +
                       " tiles missing (" + missing + (absent > listed ? ", ..." : "") + ")");
  }
  // Then the bodies, in code order, straight into the level's lists: the outline cells are held
  // once, as a whole run holds them.
  label::Outlines joined;
  joined.level = expect.level;
  joined.site_count = expect.site_count;
  joined.range = grid::whole_level(expect.level);
  std::uint64_t cells = 0;
  for (const auto& [index, tile] : tiles) cells += tile->cells;
  joined.cells.reserve(cells);
  std::size_t done = 0;
  for (auto& [index, tile] : tiles) {
    const std::size_t from = joined.cells.size();
    tile->read_body(&joined.cells, &joined.cells_per_site);
    // The tile's cells must lie in its codes, in order (the whole is checked below).
    for (std::size_t k = from; k < joined.cells.size(); ++k) {
      const grid::Code code = joined.cells[k].code();
      if (code < tile->range.first || code >= tile->range.end || (k > from && joined.cells[k - 1].code() >= code)) {
        throw tile->fail("corrupt tile product (outline cell " + std::to_string(code) + " out of place)");
      }
    }
    tile.reset();  // closes the file
    if (progress && !progress(double(++done) / double(tiles.size()))) throw Interrupted();
  }
  try {
    label::check_outlines(joined);
  } catch (const std::exception& e) {
    throw VoronoiError(std::string("-merge: the tile products do not make the level's outline cells (") + e.what() + ")");
  }
  return joined;
}

}  // namespace qtmv::pipeline
