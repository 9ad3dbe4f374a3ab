// The raster writer (see raster_writer.hpp for the layouts, bands and the choice of one type).
#include "write/raster_writer.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "gdal/error_capture.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "grid/qtm.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_strips.hpp"
#include "write/raster_types.hpp"

namespace qtmv::write {

namespace {

constexpr const char* kStage = "write";
/// The block height assumed by raster_buffer_bytes (GeoTIFF's tiles are 256 x 256).
constexpr std::uint64_t kAssumedBlockRows = 256;

bool is_vsi(const std::string& path) { return path.rfind("/vsi", 0) == 0; }

bool has_token(const char* list, const char* token) {
  if (list == nullptr) return true;  // driver does not say: let Create decide
  const CPLStringList tokens(CSLTokenizeString2(list, " ", 0));
  return tokens.FindString(token) >= 0;
}

/// Bytes a pixel of a strip takes in the writer's buffers: its values in two strip buffers (one
/// filled while GDAL writes the other), and the filler's codes and labels.
std::uint64_t strip_bytes_per_pixel(RasterOptions::Layout layout, const std::vector<RasterBand>& bands, int type_bytes) {
  return 2 * bands.size() * static_cast<std::uint64_t>(type_bytes) + StripFiller::bytes_per_pixel(layout, bands);
}

/// Bytes a pixel of a strip counts for when the strip's rows are chosen: one strip's values, and
/// every label of up to four cells (the lon/lat layout) with two codes. The strips' rows decide
/// the order of the blocks in the file (each strip's blocks are flushed band by band), so they
/// stay those of the writer that held one strip: the same file as before for the same bands.
std::uint64_t strip_row_bytes_per_pixel(RasterOptions::Layout layout, const std::vector<RasterBand>& bands, int type_bytes) {
  const std::uint64_t labels = sizeof(std::int32_t) + sizeof(float) + 1;
  return bands.size() * static_cast<std::uint64_t>(type_bytes) +
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
  if (data_type.empty() || raster_type_by_name(data_type) != GDT_Unknown) return;
  std::string names;
  for (const char* t : kRasterDataTypes) names += (names.empty() ? "" : ", ") + std::string(t);
  throw WriteError("-ot: '" + data_type + "' is not one of " + names);
}

double raster_nodata(const std::string& data_type) {
  const GDALDataType type = raster_type_by_name(data_type);
  switch (type) {
    case GDT_Byte: return 255;
    case GDT_UInt16: return 65535;
    case GDT_UInt32: return 4294967295.0;
    default: return -1;
  }
}

std::string default_raster_data_type(const std::vector<RasterBand>& bands) {
  if (has_band(bands, RasterBand::distance)) return "Float32";
  return has_band(bands, RasterBand::fid) ? "Int32" : "Byte";  // Byte: the boundary flags alone
}

std::string raster_data_type(const RasterOptions& options, bool with_distance, const sites::SiteTable& table) {
  check_raster_data_type(options.data_type);
  const std::vector<RasterBand> bands = raster_bands(options, with_distance);
  const bool fids = has_band(bands, RasterBand::fid);
  const auto all_fit = [&](GDALDataType type) {
    return !fids || std::all_of(table.sites.begin(), table.sites.end(),
                                [&](const sites::SiteRecord& site) { return fid_fits(site.fid, type); });
  };
  GDALDataType type = raster_type_by_name(options.data_type.empty() ? default_raster_data_type(bands) : options.data_type);
  // The defaults widen to Float64 for FIDs that they do not hold exactly.
  if (options.data_type.empty() && type != GDT_Byte && !all_fit(type)) type = GDT_Float64;
  if (!fids) return GDALGetDataTypeName(type);
  const std::size_t fid_band = static_cast<std::size_t>(std::find(bands.begin(), bands.end(), RasterBand::fid) - bands.begin());
  for (std::size_t s = 0; s < table.sites.size(); ++s) {
    const std::int64_t fid = table.sites[s].fid;
    if (fid_fits(fid, type)) continue;
    const std::string name = GDALGetDataTypeName(type);
    throw WriteError("band " + std::to_string(fid_band + 1) + " (site_fid): site " + std::to_string(s) + " has FID " +
                     std::to_string(fid) +
                     (fid < 0 ? ", and FIDs must be 0 or more" : ", which " + name + " does not hold exactly (" +
                                                                     range_text(type) + ")") +
                     (options.data_type.empty() ? "" : ": choose a wider -ot than " + name + ", e.g. " +
                                                           (type == GDT_Float32 ? "Float64" : "Int32 or Float64")));
  }
  return GDALGetDataTypeName(type);
}

std::uint64_t raster_buffer_bytes(int level, const RasterOptions& options, bool with_distance) {
  const RasterSize size = raster_size(level, options);
  const std::vector<RasterBand> bands = raster_bands(options, with_distance);
  // The strips' rows fill the budget as strip_row_bytes_per_pixel counts them; the second strip's
  // values come beside it.
  const std::uint64_t budget = options.strip_bytes ? options.strip_bytes : kDefaultStripBytes;
  const std::uint64_t strip = budget / strip_row_bytes_per_pixel(options.layout, bands, 8) *
                              strip_bytes_per_pixel(options.layout, bands, 8);
  const std::uint64_t row = static_cast<std::uint64_t>(size.width) * strip_bytes_per_pixel(options.layout, bands, 8);
  // Blocks wait in GDAL's cache until their row of blocks is complete; the cache writes them
  // out early (and reads them back) beyond its limit, GDAL_CACHEMAX.
  const std::uint64_t block_row = std::min<std::uint64_t>(
      static_cast<std::uint64_t>(size.width) * bands.size() * 8 *
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
  RasterSize size;  ///< the whole raster's
  int first_row, rows;  ///< the rows written: all, or a part's (RasterOptions::first_row)
  std::vector<RasterBand> bands;  ///< in the raster's order
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

std::string band_label(const RasterJob& job, std::size_t b) {
  return "band " + std::to_string(b + 1) + " (" + raster_band_description(job.bands[b]) + ")";
}

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
  // GeoTIFF and COG compress their blocks on the run's threads (the same file for any number).
  const bool gtiff = EQUAL(options.driver.c_str(), "GTiff"), cog = EQUAL(options.driver.c_str(), "COG");
  if ((gtiff || cog) && co.FetchNameValue("NUM_THREADS") == nullptr) {
    co.SetNameValue("NUM_THREADS", std::to_string(thread_count(0)).c_str());
  }
  if (gtiff) {
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
  }
  if (cog && co.FetchNameValue("RESAMPLING") == nullptr &&
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
  const int bands = static_cast<int>(job.bands.size());
  const std::uint64_t total_bytes =
      static_cast<std::uint64_t>(size.width) * static_cast<std::uint64_t>(job.rows) * job.bands.size() * job.type_bytes;
  VSIStatBufL stat;
  out.existed = VSIStatL(job.path.c_str(), &stat) == 0;
  if (job.can_create) {
    out.created = !out.existed;  // what a failed Create leaves behind is ours, an older file is not
    out.dataset = GDALCreate(job.driver, job.path.c_str(), size.width, job.rows, bands, job.type, job.co.List());
    if (out.dataset != nullptr) out.created = true;
    if (out.dataset == nullptr || job.errors.failed()) throw job.gdal_error("cannot create " + job.options.driver + " raster");
  } else if (total_bytes <= job.strip_budget || is_vsi(job.path)) {
    out.dataset = GDALCreate(GDALGetDriverByName("MEM"), "", size.width, job.rows, bands, job.type, nullptr);
    if (out.dataset == nullptr || job.errors.failed()) throw job.gdal_error("cannot create the in-memory staging raster");
  } else {
    // Too large for memory: a compressed GeoTIFF beside the destination.
    out.staging_path = job.path + ".staging.tif";
    CPLStringList staging_co;
    for (const char* option : {"TILED=YES", "COMPRESS=DEFLATE", "ZLEVEL=1", "BIGTIFF=YES"}) staging_co.AddString(option);
    staging_co.SetNameValue("NUM_THREADS", std::to_string(thread_count(0)).c_str());
    out.dataset = GDALCreate(GDALGetDriverByName("GTiff"), out.staging_path.c_str(), size.width, job.rows, bands,
                             job.type, staging_co.List());
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
  for (const auto& [name, value] : job.options.metadata) metadata.SetNameValue((prefix + name).c_str(), value.c_str());
  check(GDALSetMetadata(ds, metadata.List(), nullptr), "setting the metadata (QTM_LEVEL, QTM_LAYOUT)");
  if (!qtm) {
    // A part's first row is the whole raster's row first_row.
    double transform[6] = {-180.0, job.size.x_resolution, 0.0, 90.0 - job.first_row * job.size.y_resolution, 0.0,
                           -job.size.y_resolution};
    check(GDALSetGeoTransform(ds, transform), "setting the geotransform");
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
    const OGRErr imported = OSRImportFromEPSG(srs, 4326);
    const CPLErr set = imported == OGRERR_NONE ? GDALSetSpatialRef(ds, srs) : CE_Failure;
    OSRDestroySpatialReference(srs);
    check(set, "setting the SRS EPSG:4326");
  }
  for (std::size_t b = 0; b < job.bands.size(); ++b) {
    GDALRasterBandH band = GDALGetRasterBand(ds, static_cast<int>(b) + 1);
    GDALSetDescription(band, raster_band_description(job.bands[b]));
    if (job.errors.failed()) throw job.gdal_error(band_label(job, b) + ": setting the description");
    check(GDALSetRasterNoDataValue(band, job.nodata), band_label(job, b) + ": setting nodata");
    if (job.bands[b] == RasterBand::distance) check(GDALSetRasterUnitType(band, "m"), band_label(job, b) + ": setting the unit");
  }
}

/// Rows per strip: whole rows of the driver's blocks where the budget allows (each block written
/// once, then flushed from GDAL's cache); else at least one row, strips ending where rows of
/// blocks end.
int rows_per_strip(const RasterJob& job, int block_h) {
  const std::uint64_t row_bytes =
      static_cast<std::uint64_t>(job.size.width) * strip_row_bytes_per_pixel(job.options.layout, job.bands, job.type_bytes);
  std::uint64_t strip = std::max<std::uint64_t>(1, job.strip_budget / row_bytes);
  if (strip >= static_cast<std::uint64_t>(block_h)) {
    strip = strip / block_h * block_h;
  } else {
    while (block_h % strip != 0) --strip;
  }
  return static_cast<int>(std::min<std::uint64_t>(strip, static_cast<std::uint64_t>(job.rows)));
}

/// Fills strips on a helper thread, one strip ahead of the thread that writes them: strip n + 1's
/// cells, labels and values are made (on all cores, the helper's OpenMP team made once) while
/// GDAL writes and compresses strip n. GDAL is called from the writing thread alone.
class StripsAhead {
 public:
  explicit StripsAhead(StripFiller& filler) : filler_(filler), thread_([this] { run(); }) {}
  /// Waits for the strip being filled, then stops the helper.
  ~StripsAhead() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  StripsAhead(const StripsAhead&) = delete;
  StripsAhead& operator=(const StripsAhead&) = delete;

  /// Starts filling rows [y0, y0 + rows) into `buffer` (after the strip asked for before).
  void ask(int y0, int rows, void* buffer) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      task_ = {y0, rows, buffer};
      pending_ = true;
    }
    changed_.notify_all();
  }
  /// Waits until the strip asked for last is filled; the filler's exception comes out here.
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return !pending_; });
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }

 private:
  struct Task {
    int y0 = 0, rows = 0;
    void* buffer = nullptr;
  };
  void run() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      changed_.wait(lock, [&] { return pending_ || stop_; });
      if (stop_) return;
      const Task task = task_;
      lock.unlock();
      std::exception_ptr error;
      try {
        filler_.fill(task.y0, task.rows, task.buffer);
      } catch (...) {
        error = std::current_exception();
      }
      lock.lock();
      error_ = error;
      pending_ = false;
      changed_.notify_all();
    }
  }

  StripFiller& filler_;
  std::mutex mutex_;
  std::condition_variable changed_;
  Task task_;
  bool pending_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // last: started once the rest is made
};

/// Writes rows [y0, y0 + rows) of every band from `buffer` (band-sequential) into `ds`, and flushes
/// the blocks of a row of blocks that the strip completes from GDAL's cache (its memory follows the
/// strip).
void write_strip(const RasterJob& job, GDALDatasetH ds, int y0, int rows, int block_h, const unsigned char* buffer) {
  const int width = job.size.width;
  const std::size_t band_bytes = static_cast<std::size_t>(width) * rows * job.type_bytes;
  for (std::size_t b = 0; b < job.bands.size(); ++b) {
    void* data = const_cast<unsigned char*>(buffer + b * band_bytes);
    const CPLErr err = GDALRasterIO(GDALGetRasterBand(ds, static_cast<int>(b) + 1), GF_Write, 0, y0, width, rows, data,
                                    width, rows, job.type, 0, 0);
    if (err != CE_None || job.errors.failed()) {
      throw job.gdal_error(band_label(job, b) + ": writing rows " + std::to_string(y0) + "-" + std::to_string(y0 + rows - 1));
    }
  }
  if ((y0 + rows) % block_h != 0 && y0 + rows != job.rows) return;
  for (std::size_t b = 0; b < job.bands.size(); ++b) {
    const CPLErr err = GDALFlushRasterCache(GDALGetRasterBand(ds, static_cast<int>(b) + 1));
    if (err != CE_None || job.errors.failed()) {
      throw job.gdal_error(band_label(job, b) + ": writing rows up to " + std::to_string(y0 + rows - 1));
    }
  }
}

/// Writes the pixels into `ds`, strip by strip, each filled while the one before is written;
/// returns, per site id, 1 when some pixel holds it. A part's strips are filled from its first
/// row of the whole raster on.
std::vector<std::uint8_t> write_strips(const RasterJob& job, GDALDatasetH ds, const CellLabelSource& labels,
                                       const std::vector<std::int64_t>& fid_of) {
  const RasterSize& size = job.size;
  const RasterOptions& options = job.options;
  int block_w = 0, block_h = 0;
  GDALGetBlockSize(GDALGetRasterBand(ds, 1), &block_w, &block_h);
  block_h = std::max(1, block_h);
  const int strip_rows = rows_per_strip(job, block_h);

  StripSetup setup;
  setup.level = job.level;
  setup.layout = options.layout;
  setup.size = size;
  setup.bands = job.bands;
  setup.type = job.type;
  setup.nodata = job.nodata;
  setup.source = &labels;
  setup.fid_of = &fid_of;
  setup.threads = thread_count(0);
  StripFiller filler(setup);
  std::vector<unsigned char> buffers[2];
  for (auto& buffer : buffers) {
    buffer.resize(static_cast<std::size_t>(strip_rows) * size.width * job.bands.size() * job.type_bytes);
  }
  const double write_share = job.can_create ? 1.0 : 0.5;
  if (options.progress && !options.progress(0.0, kStage)) throw Interrupted();
  // QTMV_TRACE=write: the strips' steps (beside the writes), GDAL's writes, and the waits for strips.
  StepTrace trace(TraceStage::write);
  double io_seconds = 0, wait_seconds = 0;
  int strips = 0;
  {
    StripsAhead ahead(filler);
    const int height = job.rows, first = job.first_row;
    ahead.ask(first, std::min(strip_rows, height), buffers[0].data());
    for (int y0 = 0; y0 < height; y0 += strip_rows, ++strips) {
      const int rows = std::min(strip_rows, height - y0);
      double t = now_seconds();
      ahead.wait();
      wait_seconds += now_seconds() - t;
      filler.check(job.path);
      const int next = y0 + strip_rows;
      if (next < height) ahead.ask(first + next, std::min(strip_rows, height - next), buffers[(strips + 1) % 2].data());
      t = now_seconds();
      write_strip(job, ds, y0, rows, block_h, buffers[strips % 2].data());
      io_seconds += now_seconds() - t;
      if (options.progress && !options.progress(write_share * (y0 + rows) / height, kStage)) {
        throw Interrupted();
      }
    }
  }
  const StripTimes& times = filler.times();
  trace("raster strips", std::to_string(strips) + " strips of " + std::to_string(strip_rows) +
                             " rows, each filled while the one before is written");
  trace.note("strips' cells", times.cells);
  trace.note("strips' labels", times.labels);
  trace.note("strips' values", times.values);
  trace.note("GDAL writes", io_seconds);
  trace.note("waits for strips", wait_seconds);
  return filler.site_seen();
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
  std::vector<RasterBand> bands;
  GDALDataType type;
  try {
    bands = raster_bands(options, with_distance);
    type = GDALGetDataTypeByName(raster_data_type(options, with_distance, table).c_str());
  } catch (const WriteError& e) {
    throw WriteError(path + ": " + e.what());
  }
  const int type_bytes = GDALGetDataTypeSizeBytes(type);
  const double nodata = raster_nodata(GDALGetDataTypeName(type));
  std::vector<std::int64_t> fid_of(table.sites.size());
  for (std::size_t s = 0; s < table.sites.size(); ++s) fid_of[s] = table.sites[s].fid;
  const std::uint64_t strip_budget = options.strip_bytes ? options.strip_bytes : kDefaultStripBytes;
  const bool part = options.part_rows > 0;
  if (part && (options.first_row < 0 || options.part_rows > size.height - options.first_row)) {
    throw WriteError(path + ": rows " + std::to_string(options.first_row) + ".." +
                     std::to_string(options.first_row + options.part_rows - 1) + " are not rows of a raster of " +
                     std::to_string(size.height));
  }
  const int first_row = part ? options.first_row : 0, rows = part ? options.part_rows : size.height;

  if (GDALGetDriverCount() == 0) GDALAllRegister();
  gdal::ErrorCapture errors(gdal::ErrorCapture::Warnings::pass_on);
  GDALDriverH driver = raster_driver(path, options, type);
  const bool can_create = GDALGetMetadataItem(driver, GDAL_DCAP_CREATE, nullptr) != nullptr;
  const RasterJob job{path, options, errors, level, size, first_row, rows, bands, type, type_bytes, nodata, strip_budget, driver, can_create,
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
