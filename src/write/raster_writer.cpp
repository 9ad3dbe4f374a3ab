// The raster writer (see raster_writer.hpp for the layouts, bands and the choice of one type).
#include "write/raster_writer.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "gdal/error_capture.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "common/parallel_sort.hpp"
#include "grid/qtm.hpp"

namespace qtmv::write {

namespace {

using grid::Code;

constexpr const char* kStage = "write";
constexpr const char* kBandNames[3] = {"site_fid", "boundary", "distance_m"};
/// The data types of -ot, as GDAL names them.
constexpr const char* kDataTypes[] = {"Byte", "UInt16", "Int16", "UInt32", "Int32", "Float32", "Float64"};
/// The block height assumed by raster_buffer_bytes (GeoTIFF's tiles are 256 x 256).
constexpr std::uint64_t kAssumedBlockRows = 256;

bool is_vsi(const std::string& path) { return path.rfind("/vsi", 0) == 0; }

bool has_token(const char* list, const char* token) {
  if (list == nullptr) return true;  // driver does not say: let Create decide
  const CPLStringList tokens(CSLTokenizeString2(list, " ", 0));
  return tokens.FindString(token) >= 0;
}

bool is_integer(GDALDataType type) { return type != GDT_Float32 && type != GDT_Float64; }

/// The largest value a band of `type` holds as data (below the nodata of an unsigned type).
double largest_value(GDALDataType type) {
  switch (type) {
    case GDT_Byte: return 254;
    case GDT_UInt16: return 65534;
    case GDT_Int16: return 32767;
    case GDT_UInt32: return 4294967294.0;
    case GDT_Int32: return 2147483647.0;
    case GDT_Float32: return static_cast<double>(std::numeric_limits<float>::max());
    default: return std::numeric_limits<double>::max();
  }
}

/// Whether FID `fid` is stored exactly in a band of `type`.
bool fid_fits(std::int64_t fid, GDALDataType type) {
  if (fid < 0) return false;
  if (type == GDT_Float32) return static_cast<std::int64_t>(static_cast<float>(fid)) == fid;
  if (type == GDT_Float64) return static_cast<std::int64_t>(static_cast<double>(fid)) == fid;
  return static_cast<double>(fid) <= largest_value(type);
}

std::string range_text(GDALDataType type) {
  switch (type) {
    case GDT_Byte: return "0..254, 255 being nodata";
    case GDT_UInt16: return "0..65534, 65535 being nodata";
    case GDT_Int16: return "0..32767";
    case GDT_UInt32: return "0..4294967294, 4294967295 being nodata";
    case GDT_Int32: return "0..2147483647";
    case GDT_Float32: return "integers up to 16777216 = 2^24 and some larger ones";
    default: return "integers up to 2^53 and some larger ones";
  }
}

GDALDataType type_by_name(const std::string& name) {
  for (const char* t : kDataTypes) {
    if (EQUAL(name.c_str(), t)) return GDALGetDataTypeByName(t);
  }
  return GDT_Unknown;
}

/// The labels of one strip and the pixels' cells: what the source fills.
struct StripLabels {
  std::vector<grid::Code> pixel_code;  // lonlat: each pixel's cell (kInvalidCode: nodata)
  std::vector<grid::Code> codes;       // lonlat: the strip's cells, sorted, without repeats
  std::vector<std::int32_t> site;
  std::vector<float> distance_m;
  std::vector<std::uint8_t> boundary;
};

/// Fills row strips of band-sequential buffers of T with the labels of a CellLabelSource.
struct Filler {
  int level;
  RasterOptions::Layout layout;
  RasterSize size;
  int bands;
  GDALDataType type;
  double nodata;
  const CellLabelSource& source;
  const std::vector<std::int64_t>& fid_of;
  std::vector<std::atomic<std::uint8_t>>& seen;  // per site: some pixel holds it
  int threads;
  StripLabels labels;
  std::atomic<std::int64_t> bad_site{-1};      // first site id outside the table, if any
  std::atomic<std::int64_t> bad_distance{-1};  // a cell whose distance does not fit the type
  float bad_distance_value = 0;

  /// Asks the source for the labels of rows [y0, y0 + rows) and fills `buffer` with them.
  template <typename T>
  void fill(int y0, int rows, T* buffer) {
    const std::size_t band_space = static_cast<std::size_t>(size.width) * rows;
    const bool with_distance = bands == 3;
    if (layout == RasterOptions::Layout::qtm) {
      const Code first = row_start(y0);
      const std::size_t count = static_cast<std::size_t>(row_span(y0, rows));
      resize(count, with_distance);
      source.label_range(first, count, labels.site.data(), with_distance ? labels.distance_m.data() : nullptr,
                         labels.boundary.data());
#pragma omp parallel for num_threads(threads) schedule(dynamic, 4)
      for (int r = 0; r < rows; ++r) {
        T* out = buffer + static_cast<std::size_t>(r) * size.width;
        const Code start = row_start(y0 + r);
        const std::size_t cols = static_cast<std::size_t>(2 * row_of(y0 + r) + 1);
        for (std::size_t x = 0; x < cols; ++x) put(static_cast<std::size_t>(start - first) + x, start + x, out, x, band_space);
        for (std::size_t x = cols; x < static_cast<std::size_t>(size.width); ++x) put_nodata(out, x, band_space);
      }
      return;
    }
    // lon/lat: each pixel's cell, then the strip's cells once each.
    labels.pixel_code.resize(band_space);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 4)
    for (int r = 0; r < rows; ++r) {
      const double lat = 90.0 - (y0 + r + 0.5) * size.y_resolution;
      Code* codes = labels.pixel_code.data() + static_cast<std::size_t>(r) * size.width;
      for (std::size_t x = 0; x < static_cast<std::size_t>(size.width); ++x) {
        const double lon = -180.0 + (static_cast<double>(x) + 0.5) * size.x_resolution;
        codes[x] = grid::lonlat_to_code(lon, lat, level);  // invalid past latitude -90
      }
    }
    // Where pixels are about as fine as cells, the strip's rows of cells (a band of latitude: up
    // to one range of codes in each octant) are labelled whole, faster per cell than a list;
    // coarser pixels label the list of their cells only.
    std::uint64_t lo[8], hi[8];  // rows of each octant that the strip's pixels fall in
    for (int o = 0; o < 8; ++o) lo[o] = ~std::uint64_t{0}, hi[o] = 0;
    for (const Code code : labels.pixel_code) {
      if (code == grid::kInvalidCode) continue;
      const grid::Cell c = grid::cell_of(code, level);
      lo[c.octant] = std::min<std::uint64_t>(lo[c.octant], c.row);
      hi[c.octant] = std::max<std::uint64_t>(hi[c.octant], c.row);
    }
    std::uint64_t range_cells = 0;
    for (int o = 0; o < 8; ++o) {
      if (lo[o] <= hi[o]) range_cells += (hi[o] + 1) * (hi[o] + 1) - lo[o] * lo[o];
    }
    // The painter labels a cell several times faster than the per-cell walk of a list (more so
    // for polygons' long lists); at the equator the rows hold twice as many cells as a strip of
    // square pixels of the cell edge, so up to 4 cells a pixel take the rows.
    if (range_cells <= 4 * band_space) {
      Code start[8];
      std::size_t offset[8];
      std::size_t total = 0;
      for (int o = 0; o < 8; ++o) {
        start[o] = static_cast<Code>(o) * grid::cells_per_octant(level) + (lo[o] <= hi[o] ? lo[o] * lo[o] : 0);
        offset[o] = total;
        if (lo[o] <= hi[o]) total += static_cast<std::size_t>((hi[o] + 1) * (hi[o] + 1) - lo[o] * lo[o]);
      }
      resize(total, with_distance);
      for (int o = 0; o < 8; ++o) {
        if (lo[o] > hi[o]) continue;
        const std::size_t count = static_cast<std::size_t>((hi[o] + 1) * (hi[o] + 1) - lo[o] * lo[o]);
        source.label_range(start[o], count, labels.site.data() + offset[o],
                           with_distance ? labels.distance_m.data() + offset[o] : nullptr,
                           labels.boundary.data() + offset[o]);
      }
      const Code octant_cells = grid::cells_per_octant(level);
      put_pixels(buffer, rows, band_space, [&](Code code) {
        const int o = static_cast<int>(code / octant_cells);
        return offset[o] + static_cast<std::size_t>(code - start[o]);
      });
      return;
    }
    labels.codes = labels.pixel_code;
    parallel_sort(labels.codes.begin(), labels.codes.end(), std::less<Code>());
    labels.codes.erase(std::unique(labels.codes.begin(), labels.codes.end()), labels.codes.end());
    if (!labels.codes.empty() && labels.codes.back() == grid::kInvalidCode) labels.codes.pop_back();
    resize(labels.codes.size(), with_distance);
    source.label_codes(labels.codes.data(), labels.codes.size(), labels.site.data(),
                       with_distance ? labels.distance_m.data() : nullptr, labels.boundary.data());
    put_pixels(buffer, rows, band_space, [&](Code code) {
      return static_cast<std::size_t>(std::lower_bound(labels.codes.begin(), labels.codes.end(), code) -
                                      labels.codes.begin());
    });
  }

  /// Fills `rows` rows of pixels from the strip's pixel codes, each from the labels at
  /// index_of(code) (nodata where a pixel has no cell).
  template <typename T, class IndexOf>
  void put_pixels(T* buffer, int rows, std::size_t band_space, IndexOf&& index_of) {
#pragma omp parallel for num_threads(threads) schedule(dynamic, 4)
    for (int r = 0; r < rows; ++r) {
      T* out = buffer + static_cast<std::size_t>(r) * size.width;
      const Code* codes = labels.pixel_code.data() + static_cast<std::size_t>(r) * size.width;
      for (std::size_t x = 0; x < static_cast<std::size_t>(size.width); ++x) {
        if (codes[x] == grid::kInvalidCode) {
          put_nodata(out, x, band_space);
        } else {
          put(index_of(codes[x]), codes[x], out, x, band_space);
        }
      }
    }
  }

  Code row_start(int y) const {
    const std::uint64_t octant = static_cast<std::uint64_t>(y) >> level;
    const std::uint64_t i = row_of(y);
    return octant * grid::cells_per_octant(level) + i * i;
  }
  std::uint64_t row_of(int y) const { return static_cast<std::uint64_t>(y) & (grid::rows_per_octant(level) - 1); }
  /// Codes of rows [y0, y0 + rows): contiguous, since an octant's last row ends where the next
  /// octant's first row begins.
  std::uint64_t row_span(int y0, int rows) const {
    const int last = y0 + rows - 1;
    return row_start(last) + 2 * row_of(last) + 1 - row_start(y0);
  }

  void resize(std::size_t count, bool with_distance) {
    labels.site.resize(count);
    labels.boundary.resize(count);
    if (with_distance) labels.distance_m.resize(count);
  }

  template <typename T>
  void put(std::size_t k, Code code, T* out, std::size_t x, std::size_t band_space) {
    const std::int32_t s = labels.site[k];
    if (s < 0 || static_cast<std::size_t>(s) >= fid_of.size()) {
      std::int64_t expected = -1;
      bad_site.compare_exchange_strong(expected, s);
      put_nodata(out, x, band_space);
      return;
    }
    if (seen[s].load(std::memory_order_relaxed) == 0) seen[s].store(1, std::memory_order_relaxed);
    out[x] = static_cast<T>(fid_of[s]);  // exact: checked against the type before writing
    out[band_space + x] = static_cast<T>(labels.boundary[k]);
    if (bands == 3) {
      const float d = labels.distance_m[k];
      if (is_integer(type)) {
        const double metres = std::nearbyint(static_cast<double>(d));  // whole metres, ties to even
        if (!(metres >= 0 && metres <= largest_value(type))) {
          std::int64_t expected = -1;
          if (bad_distance.compare_exchange_strong(expected, static_cast<std::int64_t>(code))) bad_distance_value = d;
          out[2 * band_space + x] = static_cast<T>(nodata);
          return;
        }
        out[2 * band_space + x] = static_cast<T>(metres);
      } else {
        out[2 * band_space + x] = static_cast<T>(d);
      }
    }
  }

  template <typename T>
  void put_nodata(T* out, std::size_t x, std::size_t band_space) {
    for (int b = 0; b < bands; ++b) out[b * band_space + x] = static_cast<T>(nodata);
  }
};

/// A strip buffer of any band type, and Filler::fill for it.
struct StripBuffer {
  GDALDataType type;
  std::vector<unsigned char> bytes;
  template <typename T>
  T* as() { return reinterpret_cast<T*>(bytes.data()); }
  void fill(Filler& filler, int y0, int rows) {
    switch (type) {
      case GDT_Byte: filler.fill(y0, rows, as<std::uint8_t>()); break;
      case GDT_UInt16: filler.fill(y0, rows, as<std::uint16_t>()); break;
      case GDT_Int16: filler.fill(y0, rows, as<std::int16_t>()); break;
      case GDT_UInt32: filler.fill(y0, rows, as<std::uint32_t>()); break;
      case GDT_Int32: filler.fill(y0, rows, as<std::int32_t>()); break;
      case GDT_Float32: filler.fill(y0, rows, as<float>()); break;
      default: filler.fill(y0, rows, as<double>()); break;
    }
  }
};

/// Bytes a pixel of a strip takes in the writer's buffers: its bands, and its cell's labels (the
/// lon/lat layout also keeps the pixel's code, the strip's sorted codes, and the labels of up to
/// four cells a pixel when it labels the strip's rows of cells whole).
std::uint64_t strip_bytes_per_pixel(RasterOptions::Layout layout, int bands, int type_bytes) {
  const std::uint64_t labels = sizeof(std::int32_t) + sizeof(float) + 1;
  return static_cast<std::uint64_t>(bands) * type_bytes +
         (layout == RasterOptions::Layout::lonlat ? 2 * sizeof(grid::Code) + 4 * labels : labels);
}

struct CopyProgress {
  const ProgressFunc* progress;
  bool interrupted = false;
};

int CPL_STDCALL copy_progress(double fraction, const char*, void* data) {
  auto* ctx = static_cast<CopyProgress*>(data);
  if (*ctx->progress && !(*ctx->progress)(0.5 + 0.5 * fraction, kStage)) {
    ctx->interrupted = true;
    return FALSE;
  }
  return TRUE;
}

/// What write_raster has open or on disk, so that a failure can remove it.
struct Output {
  GDALDriverH driver = nullptr;
  std::string path;
  GDALDatasetH dataset = nullptr;  // the destination (Create) or the staging dataset
  bool existed = false;            // the destination existed before: keep it unless we opened it
  bool created = false;            // the destination is ours to remove on failure
  std::string staging_path;        // a staging GeoTIFF on disk, if any

  void remove_all() {
    if (dataset != nullptr) GDALClose(dataset);
    dataset = nullptr;
    // Only a regular file: never unlink a device such as /dev/full that the path named.
    VSIStatBufL stat;
    if (created && VSIStatL(path.c_str(), &stat) == 0 && VSI_ISREG(stat.st_mode)) {
      if (GDALDeleteDataset(driver, path.c_str()) != CE_None) VSIUnlink(path.c_str());
    }
    created = false;
    if (!staging_path.empty()) {
      VSIUnlink(staging_path.c_str());
      staging_path.clear();
    }
  }
};

}  // namespace

RasterSize raster_size(int level, const RasterOptions& options) {
  if (!grid::is_valid_level(level)) throw WriteError("level " + std::to_string(level) + " is outside 0..24");
  RasterSize size;
  const auto check_int = [](double pixels, const char* what) {
    if (!(pixels >= 1 && pixels <= INT_MAX)) {
      throw WriteError(std::string(what) + " of " + std::to_string(pixels) +
                       " pixels is outside 1.." + std::to_string(INT_MAX));
    }
    return static_cast<int>(pixels);
  };
  const bool tr = options.x_resolution != 0 || options.y_resolution != 0;
  const bool ts = options.width != 0 || options.height != 0;
  if (options.layout == RasterOptions::Layout::qtm) {
    if (tr || ts) throw WriteError("-tr and -ts apply to -raster lonlat only");
    const double rows = static_cast<double>(grid::rows_per_octant(level));
    size.width = check_int(2 * rows - 1, "width");
    size.height = check_int(8 * rows, "height");
    return size;
  }
  if (tr && ts) throw WriteError("-tr and -ts cannot be used together");
  if (ts) {
    if (options.width < 0 || options.height < 0) throw WriteError("-ts sizes must be positive");
    size.width = options.width ? options.width : check_int(2.0 * options.height, "width");
    size.height = options.height ? options.height : std::max(1, options.width / 2);
    size.x_resolution = 360.0 / size.width;
    size.y_resolution = 180.0 / size.height;
  } else if (tr) {
    if (!(options.x_resolution >= 0 && options.y_resolution >= 0 && std::isfinite(options.x_resolution) &&
          std::isfinite(options.y_resolution))) {
      throw WriteError("-tr resolutions must be positive (degrees)");
    }
    size.x_resolution = options.x_resolution ? options.x_resolution : options.y_resolution;
    size.y_resolution = options.y_resolution ? options.y_resolution : options.x_resolution;
    // Rounded as gdalwarp does: the resolution is kept, the extent moves by under half a pixel.
    size.width = check_int(std::max(1.0, std::floor(360.0 / size.x_resolution + 0.5)), "width");
    size.height = check_int(std::max(1.0, std::floor(180.0 / size.y_resolution + 0.5)), "height");
  } else {
    const double rows = static_cast<double>(grid::rows_per_octant(level));
    size.width = check_int(4 * rows, "width");
    size.height = check_int(2 * rows, "height");
    size.x_resolution = size.y_resolution = 90.0 / rows;
  }
  return size;
}

void check_raster_data_type(const std::string& data_type) {
  if (data_type.empty() || type_by_name(data_type) != GDT_Unknown) return;
  std::string names;
  for (const char* t : kDataTypes) names += (names.empty() ? "" : ", ") + std::string(t);
  throw WriteError("-ot: '" + data_type + "' is not one of " + names);
}

double raster_nodata(const std::string& data_type) {
  const GDALDataType type = type_by_name(data_type);
  switch (type) {
    case GDT_Byte: return 255;
    case GDT_UInt16: return 65535;
    case GDT_UInt32: return 4294967295.0;
    default: return -1;
  }
}

std::string raster_data_type(const RasterOptions& options, bool with_distance, const sites::SiteTable& table) {
  check_raster_data_type(options.data_type);
  const auto all_fit = [&](GDALDataType type) {
    return std::all_of(table.sites.begin(), table.sites.end(),
                       [&](const sites::SiteRecord& site) { return fid_fits(site.fid, type); });
  };
  GDALDataType type;
  if (!options.data_type.empty()) {
    type = type_by_name(options.data_type);
  } else if (with_distance) {
    type = all_fit(GDT_Float32) ? GDT_Float32 : GDT_Float64;
  } else {
    type = all_fit(GDT_Int32) ? GDT_Int32 : GDT_Float64;
  }
  for (std::size_t s = 0; s < table.sites.size(); ++s) {
    const std::int64_t fid = table.sites[s].fid;
    if (fid_fits(fid, type)) continue;
    const std::string name = GDALGetDataTypeName(type);
    throw WriteError("band 1 (site_fid): site " + std::to_string(s) + " has FID " + std::to_string(fid) +
                     (fid < 0 ? ", and FIDs must be 0 or more" : ", which " + name + " does not hold exactly (" +
                                                                     range_text(type) + ")") +
                     (options.data_type.empty() ? "" : ": choose a wider -ot than " + name + ", e.g. " +
                                                           (type == GDT_Float32 ? "Float64" : "Int32 or Float64")));
  }
  return GDALGetDataTypeName(type);
}

std::uint64_t raster_buffer_bytes(int level, const RasterOptions& options, bool with_distance) {
  const RasterSize size = raster_size(level, options);
  const int bands = with_distance ? 3 : 2;
  const std::uint64_t strip = options.strip_bytes ? options.strip_bytes : kDefaultStripBytes;
  const std::uint64_t row = static_cast<std::uint64_t>(size.width) * strip_bytes_per_pixel(options.layout, bands, 8);
  // Blocks wait in GDAL's cache until their row of blocks is complete; the cache writes them
  // out early (and reads them back) beyond its limit, GDAL_CACHEMAX.
  const std::uint64_t block_row = std::min<std::uint64_t>(
      static_cast<std::uint64_t>(size.width) * bands * 8 *
          std::min<std::uint64_t>(kAssumedBlockRows, static_cast<std::uint64_t>(size.height)),
      static_cast<std::uint64_t>(std::max<GIntBig>(0, GDALGetCacheMax64())));
  return std::max({strip, row, block_row});
}

RasterWritten write_raster(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                           const RasterOptions& options) {
  if (labels.site == nullptr) throw WriteError(path + ": no labels to write");
  return write_raster(path, DenseLabelSource(labels), table, options);
}

namespace {

/// What write_raster settles before it creates anything: the grid, the band type, the driver and
/// its creation options; and GDAL's errors meanwhile.
struct RasterJob {
  const std::string& path;
  const RasterOptions& options;
  gdal::ErrorCapture& errors;
  int level;
  RasterSize size;
  int bands;
  GDALDataType type;
  int type_bytes;
  double nodata;
  std::uint64_t strip_budget;
  GDALDriverH driver;
  bool can_create;  ///< the driver creates the file (else a staging dataset is copied to it)
  CPLStringList co;

  /// A failure of GDAL's, with its message.
  WriteError gdal_error(const std::string& what) const {
    const std::string gdal = errors.take();
    return WriteError(path + ": " + what + ": " + (gdal.empty() ? "no message from GDAL" : gdal));
  }
};

std::string band_label(int b) { return "band " + std::to_string(b + 1) + " (" + kBandNames[b] + ")"; }

/// options.driver, if it writes rasters of `type`.
GDALDriverH raster_driver(const std::string& path, const RasterOptions& options, GDALDataType type) {
  const std::string& name = options.driver;
  GDALDriverH driver = GDALGetDriverByName(name.c_str());
  if (driver == nullptr) throw WriteError(path + ": unknown raster driver '" + name + "' (see --formats)");
  if (GDALGetMetadataItem(driver, GDAL_DCAP_RASTER, nullptr) == nullptr) {
    throw WriteError(path + ": driver " + name + " does not write rasters");
  }
  const bool can_create = GDALGetMetadataItem(driver, GDAL_DCAP_CREATE, nullptr) != nullptr;
  const bool can_copy = GDALGetMetadataItem(driver, GDAL_DCAP_CREATECOPY, nullptr) != nullptr;
  if (!can_create && !can_copy) throw WriteError(path + ": driver " + name + " cannot create files");
  const char* types = GDALGetMetadataItem(driver, GDAL_DMD_CREATIONDATATYPES, nullptr);
  if (!has_token(types, GDALGetDataTypeName(type))) {
    throw WriteError(path + ": driver " + name + " cannot hold " + GDALGetDataTypeName(type) + " bands (it creates " +
                     types + ")" + (options.data_type.empty() ? "; -ot names another type, if the values fit it" : "") +
                     "; use GTiff or another format");
  }
  return driver;
}

/// The creation options: the caller's, and GeoTIFF's defaults where the caller sets none.
CPLStringList creation_options(const RasterOptions& options) {
  CPLStringList co;
  for (const auto& option : options.creation_options) co.AddString(option.c_str());
  if (EQUAL(options.driver.c_str(), "GTiff")) {
    // Measured at level 11 (135 000 sites, 2 cores): DEFLATE at its default ZLEVEL 6, pixel
    // interleaved, single-threaded took 28 s; ZLEVEL=1, band interleaved, compressing on all
    // cores 5 s, and the file is 5% smaller (each band compresses on its own).
    if (co.FetchNameValue("TILED") == nullptr) co.SetNameValue("TILED", "YES");
    if (co.FetchNameValue("COMPRESS") == nullptr) {
      co.SetNameValue("COMPRESS", "DEFLATE");
      if (co.FetchNameValue("ZLEVEL") == nullptr) co.SetNameValue("ZLEVEL", "1");
    }
    if (co.FetchNameValue("BIGTIFF") == nullptr) co.SetNameValue("BIGTIFF", "IF_SAFER");
    if (co.FetchNameValue("INTERLEAVE") == nullptr) co.SetNameValue("INTERLEAVE", "BAND");
    if (co.FetchNameValue("NUM_THREADS") == nullptr) co.SetNameValue("NUM_THREADS", "ALL_CPUS");
  }
  if (EQUAL(options.driver.c_str(), "COG") && co.FetchNameValue("RESAMPLING") == nullptr &&
      co.FetchNameValue("OVERVIEW_RESAMPLING") == nullptr) {
    // The FID and boundary bands are categories: the driver's default (CUBIC) made overview
    // pixels of FIDs that are no site (-8.86, 190.2). One method serves every band.
    co.SetNameValue("RESAMPLING", "NEAREST");
  }
  return co;
}

/// Creates the dataset written strip by strip (out.dataset): the destination, or a staging copy.
void create_dataset(const RasterJob& job, Output& out) {
  const RasterSize& size = job.size;
  const std::uint64_t total_bytes =
      static_cast<std::uint64_t>(size.width) * static_cast<std::uint64_t>(size.height) * job.bands * job.type_bytes;
  VSIStatBufL stat;
  out.existed = VSIStatL(job.path.c_str(), &stat) == 0;
  if (job.can_create) {
    out.created = !out.existed;  // what a failed Create leaves behind is ours, an older file is not
    out.dataset = GDALCreate(job.driver, job.path.c_str(), size.width, size.height, job.bands, job.type, job.co.List());
    if (out.dataset != nullptr) out.created = true;
    if (out.dataset == nullptr || job.errors.failed()) throw job.gdal_error("cannot create " + job.options.driver + " raster");
  } else if (total_bytes <= job.strip_budget || is_vsi(job.path)) {
    out.dataset = GDALCreate(GDALGetDriverByName("MEM"), "", size.width, size.height, job.bands, job.type, nullptr);
    if (out.dataset == nullptr || job.errors.failed()) throw job.gdal_error("cannot create the in-memory staging raster");
  } else {
    // Too large for memory: a compressed GeoTIFF beside the destination.
    out.staging_path = job.path + ".staging.tif";
    const char* staging_co[] = {"TILED=YES", "COMPRESS=DEFLATE", "BIGTIFF=YES", nullptr};
    out.dataset = GDALCreate(GDALGetDriverByName("GTiff"), out.staging_path.c_str(), size.width, size.height, job.bands,
                             job.type, const_cast<char**>(staging_co));
    if (out.dataset == nullptr || job.errors.failed()) throw job.gdal_error("cannot create staging raster " + out.staging_path);
  }
}

/// The dataset's description: metadata, band names, nodata, georeferencing.
void describe_dataset(const RasterJob& job, GDALDatasetH ds) {
  const bool qtm = job.options.layout == RasterOptions::Layout::qtm;
  auto check = [&](CPLErr err, const std::string& what) {
    if (err != CE_None || job.errors.failed()) throw job.gdal_error(what);
  };
  // Set as one list: netCDF refuses single items (it takes global attributes as NC_GLOBAL#NAME).
  const std::string prefix = job.options.driver == "netCDF" ? "NC_GLOBAL#" : "";
  CPLStringList metadata(CSLDuplicate(GDALGetMetadata(ds, nullptr)));
  metadata.SetNameValue((prefix + "QTM_LEVEL").c_str(), std::to_string(job.level).c_str());
  metadata.SetNameValue((prefix + "QTM_LAYOUT").c_str(), qtm ? "octant_row_col" : "lonlat");
  if (qtm) {
    // Not georeferenced: say so, and how a pixel maps to a cell.
    metadata.SetNameValue((prefix + "QTM_GEOREFERENCED").c_str(), "NO");
    metadata.SetNameValue((prefix + "QTM_PIXEL").c_str(),
                          "column j, row octant * 2^QTM_LEVEL + i for cell (octant, i, j); nodata where j > 2i");
  }
  check(GDALSetMetadata(ds, metadata.List(), nullptr), "setting the metadata (QTM_LEVEL, QTM_LAYOUT)");
  if (!qtm) {
    double transform[6] = {-180.0, job.size.x_resolution, 0.0, 90.0, 0.0, -job.size.y_resolution};
    check(GDALSetGeoTransform(ds, transform), "setting the geotransform");
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
    const OGRErr imported = OSRImportFromEPSG(srs, 4326);
    const CPLErr set = imported == OGRERR_NONE ? GDALSetSpatialRef(ds, srs) : CE_Failure;
    OSRDestroySpatialReference(srs);
    check(set, "setting the SRS EPSG:4326");
  }
  for (int b = 0; b < job.bands; ++b) {
    GDALRasterBandH band = GDALGetRasterBand(ds, b + 1);
    GDALSetDescription(band, kBandNames[b]);
    if (job.errors.failed()) throw job.gdal_error(band_label(b) + ": setting the description");
    check(GDALSetRasterNoDataValue(band, job.nodata), band_label(b) + ": setting nodata");
    if (b == 2) check(GDALSetRasterUnitType(band, "m"), band_label(b) + ": setting the unit");
  }
}

/// Writes the pixels into `ds`, strip by strip; returns, per site id, 1 when some pixel holds it.
std::vector<std::uint8_t> write_strips(const RasterJob& job, GDALDatasetH ds, const CellLabelSource& labels,
                                       const std::vector<std::int64_t>& fid_of) {
  const RasterSize& size = job.size;
  const int bands = job.bands, type_bytes = job.type_bytes;
  const GDALDataType type = job.type;
  const RasterOptions& options = job.options;
  // Strips of whole rows of blocks where the budget allows (each block written once, then
  // flushed from GDAL's cache); else at least one row, and the blocks flushed when their row
  // of blocks is complete.
  int block_w = 0, block_h = 0;
  GDALGetBlockSize(GDALGetRasterBand(ds, 1), &block_w, &block_h);
  block_h = std::max(1, block_h);
  const std::uint64_t row_bytes = static_cast<std::uint64_t>(size.width) * strip_bytes_per_pixel(options.layout, bands, type_bytes);
  std::uint64_t strip = std::max<std::uint64_t>(1, job.strip_budget / row_bytes);
  if (strip >= static_cast<std::uint64_t>(block_h)) {
    strip = strip / block_h * block_h;
  } else {
    while (block_h % strip != 0) --strip;  // strips that end where rows of blocks end
  }
  strip = std::min<std::uint64_t>(strip, static_cast<std::uint64_t>(size.height));
  const int strip_rows = static_cast<int>(strip);

  std::vector<std::atomic<std::uint8_t>> seen(fid_of.size());
  for (auto& flag : seen) flag.store(0, std::memory_order_relaxed);
  Filler filler{job.level, options.layout, size, bands, type, job.nodata, labels, fid_of, seen, thread_count(0), {}, {-1}, {-1}, 0};
  StripBuffer buffer{type, {}};
  buffer.bytes.resize(strip * size.width * bands * type_bytes);
  const double write_share = job.can_create ? 1.0 : 0.5;
  if (options.progress && !options.progress(0.0, kStage)) throw Interrupted();
  // QTMV_TRACE=write: the strips' totals (labels and pixels, GDAL's writes).
  double fill_seconds = 0, io_seconds = 0;
  int strips = 0;
  for (int y0 = 0; y0 < size.height; y0 += strip_rows) {
    const int rows = std::min(strip_rows, size.height - y0);
    double t = now_seconds();
    buffer.fill(filler, y0, rows);
    fill_seconds += now_seconds() - t;
    t = now_seconds();
    ++strips;
    if (filler.bad_site >= 0) {
      throw WriteError(job.path + ": band 1 (site_fid): site id " + std::to_string(filler.bad_site.load()) +
                       " is not in the site table (" + std::to_string(fid_of.size()) + " sites)");
    }
    if (filler.bad_distance >= 0) {
      char metres[64];
      std::snprintf(metres, sizeof metres, "%.1f", static_cast<double>(filler.bad_distance_value));
      throw WriteError(job.path + ": band 3 (distance_m): cell " + std::to_string(filler.bad_distance.load()) +
                       " is " + metres + " m from its site, outside " + GDALGetDataTypeName(type) + " (" +
                       range_text(type) + "; distances are rounded to whole metres): choose a wider -ot, e.g. " +
                       "UInt32, Int32 or Float32");
    }
    const std::size_t band_space = static_cast<std::size_t>(size.width) * rows;
    for (int b = 0; b < bands; ++b) {
      void* data = buffer.bytes.data() + b * band_space * type_bytes;
      const CPLErr err =
          GDALRasterIO(GDALGetRasterBand(ds, b + 1), GF_Write, 0, y0, size.width, rows, data, size.width, rows, type, 0, 0);
      if (err != CE_None || job.errors.failed()) {
        throw job.gdal_error(band_label(b) + ": writing rows " + std::to_string(y0) + "-" + std::to_string(y0 + rows - 1));
      }
    }
    // A complete row of blocks leaves GDAL's cache now: its memory follows the strip.
    if ((y0 + rows) % block_h == 0 || y0 + rows == size.height) {
      for (int b = 0; b < bands; ++b) {
        const CPLErr err = GDALFlushRasterCache(GDALGetRasterBand(ds, b + 1));
        if (err != CE_None || job.errors.failed()) {
          throw job.gdal_error(band_label(b) + ": writing rows up to " + std::to_string(y0 + rows - 1));
        }
      }
    }
    io_seconds += now_seconds() - t;
    if (options.progress && !options.progress(write_share * (y0 + rows) / size.height, kStage)) {
      throw Interrupted();
    }
  }
  std::vector<std::uint8_t> site_seen(seen.size());
  for (std::size_t k = 0; k < seen.size(); ++k) site_seen[k] = seen[k].load(std::memory_order_relaxed);
  trace_printf(TraceStage::write, "raster %d strips of %d rows: labels and pixels %.3f s, GDAL writes %.3f s", strips,
               strip_rows, fill_seconds, io_seconds);
  return site_seen;
}

/// Closes the dataset written (out.dataset), or copies the staging dataset to the destination and
/// removes it (GDAL 3.6's GDALClose returns nothing: the error state tells).
void close_dataset(const RasterJob& job, Output& out) {
  const std::string& name = job.options.driver;
  GDALDatasetH ds = out.dataset;
  if (job.can_create) {
    GDALFlushCache(ds);
    out.dataset = nullptr;
    GDALClose(ds);
    if (job.errors.failed()) throw job.gdal_error("closing the " + name + " raster");
  } else {
    GDALFlushCache(ds);
    if (job.errors.failed()) throw job.gdal_error("writing the staging raster");
    CopyProgress ctx{&job.options.progress};
    out.created = !out.existed;
    GDALDatasetH copy = GDALCreateCopy(job.driver, job.path.c_str(), ds, FALSE, job.co.List(), copy_progress, &ctx);
    if (copy != nullptr) out.created = true;
    if (ctx.interrupted) {
      if (copy != nullptr) GDALClose(copy);
      throw Interrupted();
    }
    if (copy == nullptr || job.errors.failed()) {
      if (copy != nullptr) GDALClose(copy);
      throw job.gdal_error("copying to " + name);
    }
    GDALClose(copy);
    if (job.errors.failed()) throw job.gdal_error("closing the " + name + " raster");
    out.dataset = nullptr;
    GDALClose(ds);
    if (!out.staging_path.empty()) VSIUnlink(out.staging_path.c_str());
    out.staging_path.clear();
    job.errors.take();  // the staging copy's own messages do not concern the destination
  }
}

}  // namespace

RasterWritten write_raster(const std::string& path, const CellLabelSource& labels, const sites::SiteTable& table,
                           const RasterOptions& options) {
  const int level = labels.level();
  RasterSize size;
  try {
    size = raster_size(level, options);
  } catch (const WriteError& e) {
    throw WriteError(path + ": " + e.what());
  }
  const bool with_distance = labels.has_distance();
  const int bands = with_distance ? 3 : 2;
  GDALDataType type;
  try {
    type = GDALGetDataTypeByName(raster_data_type(options, with_distance, table).c_str());
  } catch (const WriteError& e) {
    throw WriteError(path + ": " + e.what());
  }
  const int type_bytes = GDALGetDataTypeSizeBytes(type);
  const double nodata = raster_nodata(GDALGetDataTypeName(type));
  std::vector<std::int64_t> fid_of(table.sites.size());
  for (std::size_t s = 0; s < table.sites.size(); ++s) fid_of[s] = table.sites[s].fid;
  const std::uint64_t strip_budget = options.strip_bytes ? options.strip_bytes : kDefaultStripBytes;

  if (GDALGetDriverCount() == 0) GDALAllRegister();
  gdal::ErrorCapture errors(gdal::ErrorCapture::Warnings::pass_on);
  GDALDriverH driver = raster_driver(path, options, type);
  const bool can_create = GDALGetMetadataItem(driver, GDAL_DCAP_CREATE, nullptr) != nullptr;
  const RasterJob job{path, options, errors, level, size, bands, type, type_bytes, nodata, strip_budget, driver, can_create,
                      creation_options(options)};

  RasterWritten written;
  Output out;
  out.driver = driver;
  out.path = path;
  try {
    create_dataset(job, out);
    describe_dataset(job, out.dataset);
    written.site_seen = write_strips(job, out.dataset, labels, fid_of);
    close_dataset(job, out);
  } catch (...) {
    out.remove_all();
    errors.take();  // what the clean-up said would only confuse
    throw;
  }
  return written;
}

}  // namespace qtmv::write
