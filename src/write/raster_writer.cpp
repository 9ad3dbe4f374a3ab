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
#include <limits>
#include <string>
#include <vector>

#include "gdal/error_capture.hpp"
#include "grid/qtm.hpp"

namespace qtmv::write {

namespace {

using grid::Code;

constexpr const char* kStage = "write";
constexpr const char* kBandNames[3] = {"site_fid", "boundary", "distance_m"};
/// Largest staging dataset kept in memory for CreateCopy-only drivers (bytes).
constexpr std::uint64_t kMemStagingLimit = std::uint64_t{1} << 30;
/// A row strip: at least this many pixels per RasterIO, at most this many bytes of buffer.
constexpr std::uint64_t kStripPixels = std::uint64_t{1} << 20;
constexpr std::uint64_t kStripBytesMax = std::uint64_t{64} << 20;

bool is_vsi(const std::string& path) { return path.rfind("/vsi", 0) == 0; }

bool has_token(const char* list, const char* token) {
  if (list == nullptr) return true;  // driver does not say: let Create decide
  const CPLStringList tokens(CSLTokenizeString2(list, " ", 0));
  return tokens.FindString(token) >= 0;
}

/// Fills row strips of band-sequential buffers of T (int32 or double), nodata -1.
struct Filler {
  int level;
  RasterOptions::Layout layout;
  RasterSize size;
  int bands;
  const CellLabels& labels;
  const std::vector<std::int32_t>& fid_of;
  std::atomic<std::int64_t> bad_site{-1};  // first site id outside the table, if any

  template <typename T>
  void fill(int y0, int rows, T* buffer) {
    const std::size_t band_space = static_cast<std::size_t>(size.width) * rows;
#pragma omp parallel for schedule(dynamic, 4)
    for (int r = 0; r < rows; ++r) {
      T* out = buffer + static_cast<std::size_t>(r) * size.width;
      if (layout == RasterOptions::Layout::qtm) {
        fill_qtm_row(y0 + r, out, band_space);
      } else {
        fill_lonlat_row(y0 + r, out, band_space);
      }
    }
  }

  template <typename T>
  void put(Code code, T* out, std::size_t x, std::size_t band_space) {
    const std::int32_t s = labels.site[code];
    if (s < 0 || static_cast<std::size_t>(s) >= fid_of.size()) {
      if (s >= 0) {
        std::int64_t expected = -1;
        bad_site.compare_exchange_strong(expected, s);
      }
      put_nodata(out, x, band_space);
      return;
    }
    out[x] = static_cast<T>(fid_of[s]);
    out[band_space + x] = static_cast<T>(is_boundary(labels, code));
    if (bands == 3) out[2 * band_space + x] = static_cast<T>(labels.distance_m[code]);
  }

  template <typename T>
  void put_nodata(T* out, std::size_t x, std::size_t band_space) {
    for (int b = 0; b < bands; ++b) out[b * band_space + x] = static_cast<T>(kRasterNodata);
  }

  template <typename T>
  void fill_qtm_row(int y, T* out, std::size_t band_space) {
    const std::uint64_t rows_per = grid::rows_per_octant(level);
    const std::uint64_t octant = static_cast<std::uint64_t>(y) >> level;
    const std::uint64_t i = static_cast<std::uint64_t>(y) & (rows_per - 1);
    const Code row_start = octant * grid::cells_per_octant(level) + i * i;
    const std::size_t cols = static_cast<std::size_t>(2 * i + 1);
    for (std::size_t x = 0; x < cols; ++x) put(row_start + x, out, x, band_space);
    for (std::size_t x = cols; x < static_cast<std::size_t>(size.width); ++x) put_nodata(out, x, band_space);
  }

  template <typename T>
  void fill_lonlat_row(int y, T* out, std::size_t band_space) {
    const double lat = 90.0 - (y + 0.5) * size.y_resolution;
    for (std::size_t x = 0; x < static_cast<std::size_t>(size.width); ++x) {
      const double lon = -180.0 + (static_cast<double>(x) + 0.5) * size.x_resolution;
      const Code code = grid::lonlat_to_code(lon, lat, level);  // invalid past latitude -90
      if (code == grid::kInvalidCode) {
        put_nodata(out, x, band_space);
      } else {
        put(code, out, x, band_space);
      }
    }
  }
};

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

void write_raster(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const RasterOptions& options) {
  if (labels.site == nullptr) throw WriteError(path + ": no labels to write");
  const int level = labels.level;
  RasterSize size;
  try {
    size = raster_size(level, options);
  } catch (const WriteError& e) {
    throw WriteError(path + ": " + e.what());
  }
  const bool with_distance = labels.distance_m != nullptr;
  const int bands = with_distance ? 3 : 2;
  const GDALDataType type = with_distance ? GDT_Float64 : GDT_Int32;
  const int type_bytes = GDALGetDataTypeSizeBytes(type);

  // Band 1 is specified as Int32: a FID outside it is an error, not a wrapped value.
  std::vector<std::int32_t> fid_of(table.sites.size());
  for (std::size_t s = 0; s < table.sites.size(); ++s) {
    const std::int64_t fid = table.sites[s].fid;
    if (fid < 0 || fid > std::numeric_limits<std::int32_t>::max()) {
      throw WriteError(path + ": band 1 (site_fid): site " + std::to_string(s) + " has FID " + std::to_string(fid) +
                       ", outside 0.." + std::to_string(std::numeric_limits<std::int32_t>::max()));
    }
    fid_of[s] = static_cast<std::int32_t>(fid);
  }

  if (GDALGetDriverCount() == 0) GDALAllRegister();
  gdal::ErrorCapture errors(gdal::ErrorCapture::Warnings::pass_on);
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
                     types + "); band 1 (site_fid) needs Int32" +
                     (with_distance ? ", and with band 3 (distance_m) all bands are Float64" : "") +
                     "; use GTiff or another format");
  }

  CPLStringList co;
  for (const auto& option : options.creation_options) co.AddString(option.c_str());
  if (EQUAL(name.c_str(), "GTiff")) {
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

  const auto gdal_error = [&](const std::string& what) {
    const std::string gdal = errors.take();
    return WriteError(path + ": " + what + ": " + (gdal.empty() ? "no message from GDAL" : gdal));
  };
  const auto band_label = [](int b) { return "band " + std::to_string(b + 1) + " (" + kBandNames[b] + ")"; };

  Output out;
  out.driver = driver;
  out.path = path;
  try {
    // --- the dataset written strip by strip: the destination, or a staging copy ---------------
    const std::uint64_t total_bytes =
        static_cast<std::uint64_t>(size.width) * static_cast<std::uint64_t>(size.height) * bands * type_bytes;
    VSIStatBufL stat;
    out.existed = VSIStatL(path.c_str(), &stat) == 0;
    if (can_create) {
      out.created = !out.existed;  // what a failed Create leaves behind is ours, an older file is not
      out.dataset = GDALCreate(driver, path.c_str(), size.width, size.height, bands, type, co.List());
      if (out.dataset != nullptr) out.created = true;
      if (out.dataset == nullptr || errors.failed()) throw gdal_error("cannot create " + name + " raster");
    } else if (total_bytes <= kMemStagingLimit || is_vsi(path)) {
      out.dataset = GDALCreate(GDALGetDriverByName("MEM"), "", size.width, size.height, bands, type, nullptr);
      if (out.dataset == nullptr || errors.failed()) throw gdal_error("cannot create the in-memory staging raster");
    } else {
      // Too large for memory: a compressed GeoTIFF beside the destination.
      out.staging_path = path + ".staging.tif";
      const char* staging_co[] = {"TILED=YES", "COMPRESS=DEFLATE", "BIGTIFF=YES", nullptr};
      out.dataset = GDALCreate(GDALGetDriverByName("GTiff"), out.staging_path.c_str(), size.width, size.height, bands,
                               type, const_cast<char**>(staging_co));
      if (out.dataset == nullptr || errors.failed()) throw gdal_error("cannot create staging raster " + out.staging_path);
    }
    GDALDatasetH ds = out.dataset;

    // --- description: metadata, band names, nodata, georeferencing -----------------------------
    const bool qtm = options.layout == RasterOptions::Layout::qtm;
    auto check = [&](CPLErr err, const std::string& what) {
      if (err != CE_None || errors.failed()) throw gdal_error(what);
    };
    check(GDALSetMetadataItem(ds, "QTM_LEVEL", std::to_string(level).c_str(), nullptr), "setting metadata QTM_LEVEL");
    check(GDALSetMetadataItem(ds, "QTM_LAYOUT", qtm ? "octant_row_col" : "lonlat", nullptr),
          "setting metadata QTM_LAYOUT");
    if (qtm) {
      // Not georeferenced: say so, and how a pixel maps to a cell.
      check(GDALSetMetadataItem(ds, "QTM_GEOREFERENCED", "NO", nullptr), "setting metadata QTM_GEOREFERENCED");
      check(GDALSetMetadataItem(ds, "QTM_PIXEL",
                                "column j, row octant * 2^QTM_LEVEL + i for cell (octant, i, j); nodata where j > 2i",
                                nullptr),
            "setting metadata QTM_PIXEL");
    } else {
      double transform[6] = {-180.0, size.x_resolution, 0.0, 90.0, 0.0, -size.y_resolution};
      check(GDALSetGeoTransform(ds, transform), "setting the geotransform");
      OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
      OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
      const OGRErr imported = OSRImportFromEPSG(srs, 4326);
      const CPLErr set = imported == OGRERR_NONE ? GDALSetSpatialRef(ds, srs) : CE_Failure;
      OSRDestroySpatialReference(srs);
      check(set, "setting the SRS EPSG:4326");
    }
    for (int b = 0; b < bands; ++b) {
      GDALRasterBandH band = GDALGetRasterBand(ds, b + 1);
      GDALSetDescription(band, kBandNames[b]);
      if (errors.failed()) throw gdal_error(band_label(b) + ": setting the description");
      check(GDALSetRasterNoDataValue(band, kRasterNodata), band_label(b) + ": setting nodata");
      if (b == 2) check(GDALSetRasterUnitType(band, "m"), band_label(b) + ": setting the unit");
    }

    // --- the pixels, strip by strip ---------------------------------------------------------------
    int block_w = 0, block_h = 0;
    GDALGetBlockSize(GDALGetRasterBand(ds, 1), &block_w, &block_h);
    block_h = std::max(1, block_h);
    const std::uint64_t row_bytes = static_cast<std::uint64_t>(size.width) * bands * type_bytes;
    std::uint64_t strip = std::max<std::uint64_t>(1, kStripPixels / size.width);
    strip = (strip + block_h - 1) / block_h * block_h;  // whole blocks: each tile is written once
    strip = std::max<std::uint64_t>(1, std::min<std::uint64_t>(strip, kStripBytesMax / row_bytes));
    strip = std::min<std::uint64_t>(strip, static_cast<std::uint64_t>(size.height));
    const int strip_rows = static_cast<int>(strip);

    Filler filler{level, options.layout, size, bands, labels, fid_of};
    std::vector<std::int32_t> ints;
    std::vector<double> doubles;
    (type == GDT_Int32 ? ints.resize(strip * size.width * bands) : doubles.resize(strip * size.width * bands));
    const double write_share = can_create ? 1.0 : 0.5;
    if (options.progress && !options.progress(0.0, kStage)) throw Interrupted();
    for (int y0 = 0; y0 < size.height; y0 += strip_rows) {
      const int rows = std::min(strip_rows, size.height - y0);
      void* buffer;
      if (type == GDT_Int32) {
        filler.fill(y0, rows, ints.data());
        buffer = ints.data();
      } else {
        filler.fill(y0, rows, doubles.data());
        buffer = doubles.data();
      }
      if (filler.bad_site >= 0) {
        throw WriteError(path + ": band 1 (site_fid): site id " + std::to_string(filler.bad_site.load()) +
                         " is not in the site table (" + std::to_string(fid_of.size()) + " sites)");
      }
      const std::size_t band_space = static_cast<std::size_t>(size.width) * rows;
      for (int b = 0; b < bands; ++b) {
        void* data = static_cast<char*>(buffer) + b * band_space * type_bytes;
        const CPLErr err =
            GDALRasterIO(GDALGetRasterBand(ds, b + 1), GF_Write, 0, y0, size.width, rows, data, size.width, rows, type, 0, 0);
        if (err != CE_None || errors.failed()) {
          throw gdal_error(band_label(b) + ": writing rows " + std::to_string(y0) + "-" + std::to_string(y0 + rows - 1));
        }
      }
      if (options.progress && !options.progress(write_share * (y0 + rows) / size.height, kStage)) {
        throw Interrupted();
      }
    }

    // --- close (GDAL 3.6's GDALClose returns nothing: the error state tells) --------------------
    if (can_create) {
      GDALFlushCache(ds);
      out.dataset = nullptr;
      GDALClose(ds);
      if (errors.failed()) throw gdal_error("closing the " + name + " raster");
    } else {
      GDALFlushCache(ds);
      if (errors.failed()) throw gdal_error("writing the staging raster");
      CopyProgress ctx{&options.progress};
      out.created = !out.existed;
      GDALDatasetH copy = GDALCreateCopy(driver, path.c_str(), ds, FALSE, co.List(), copy_progress, &ctx);
      if (copy != nullptr) out.created = true;
      if (ctx.interrupted) {
        if (copy != nullptr) GDALClose(copy);
        throw Interrupted();
      }
      if (copy == nullptr || errors.failed()) {
        if (copy != nullptr) GDALClose(copy);
        throw gdal_error("copying to " + name);
      }
      GDALClose(copy);
      if (errors.failed()) throw gdal_error("closing the " + name + " raster");
      out.dataset = nullptr;
      GDALClose(ds);
      if (!out.staging_path.empty()) VSIUnlink(out.staging_path.c_str());
      out.staging_path.clear();
      errors.take();  // the staging copy's own messages do not concern the destination
    }
  } catch (...) {
    out.remove_all();
    errors.take();  // what the clean-up said would only confuse
    throw;
  }
}

}  // namespace qtmv::write
