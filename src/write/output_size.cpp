// The output's size against the free disk space (see output_size.hpp).
#include "write/output_size.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <system_error>

#include "common/config_option.hpp"
#include "grid/qtm.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_writer.hpp"

namespace qtmv::write {

OutputSize estimate_raster_size(int level, const RasterOptions& options, bool with_distance) {
  const RasterSize size = raster_size(level, options);
  const std::vector<RasterBand> band_list = raster_bands(options, with_distance);
  const std::uint64_t bands = band_list.size();
  check_raster_data_type(options.data_type);
  // The default before the FIDs are known (larger FIDs make it Float64 later).
  const std::string type = options.data_type.empty() ? default_raster_data_type(band_list) : options.data_type;
  const GDALDataType gdal_type = GDALGetDataTypeByName(type.c_str());
  const std::uint64_t bytes_per_sample = static_cast<std::uint64_t>(GDALGetDataTypeSizeBytes(gdal_type));
  const int rows = options.part_rows > 0 ? options.part_rows : size.height;  // a part's rows only
  OutputSize out;
  out.bytes = static_cast<std::uint64_t>(size.width) * static_cast<std::uint64_t>(rows) * bands * bytes_per_sample;
  out.what = std::to_string(size.width) + " x " + std::to_string(rows) + " pixels, " + std::to_string(bands) +
             " bands of " + GDALGetDataTypeName(gdal_type);
  const bool sized = options.width > 0 || options.height > 0 || options.x_resolution > 0 || options.y_resolution > 0;
  out.smaller = options.layout == RasterOptions::Layout::lonlat && sized ? "fewer pixels (-tr, -ts)" : "a lower -level";
  return out;
}

std::uint64_t bytes_per_cell_row(const std::string& driver) {
  const std::string d = CPLString(driver).toupper();
  if (d == "GPKG" || d == "SQLITE") return 150;
  // Text formats write each coordinate as 15 to 17 digits.
  if (d == "GEOJSON" || d == "GEOJSONSEQ" || d == "CSV" || d == "KML" || d == "GML" || d == "LIBKML") return 300;
  return 200;
}

OutputSize estimate_vector_size(int level, const VectorOptions& options) {
  OutputSize out;
  if (std::find(options.layers.begin(), options.layers.end(), "cells") == options.layers.end()) return out;
  const std::uint64_t cells = grid::cell_count(level);
  const std::uint64_t per_row = bytes_per_cell_row(options.driver);
  out.bytes = cells * per_row;
  out.what = std::to_string(cells) + " rows of about " + std::to_string(per_row) + " bytes";
  out.smaller = "a lower -level, or -layers without cells";
  return out;
}

std::uint64_t expected_vector_bytes(int level, const VectorOptions& options, std::uint64_t outline_cells) {
  const bool other_layers = std::any_of(options.layers.begin(), options.layers.end(),
                                        [](const std::string& name) { return name != "cells"; });
  return estimate_vector_size(level, options).bytes + (other_layers ? kBytesPerOutlineCell * outline_cells : 0);
}

std::string format_bytes(double bytes) {
  static const char* const units[] = {"bytes", "kB", "MB", "GB", "TB", "PB", "EB"};
  int unit = 0;
  while (bytes >= 1000.0 && unit < 6) {
    bytes /= 1000.0;
    ++unit;
  }
  char text[64];
  std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.1f %s", bytes, units[unit]);
  return text;
}

void check_disk_space(const std::string& destination, const OutputSize& size, const std::string& kind) {
  if (size.bytes == 0 || destination.rfind("/vsi", 0) == 0) return;
  if (!CPLTestBool(CPLGetConfigOption("CHECK_DISK_FREE_SPACE", "YES"))) return;
  namespace fs = std::filesystem;
  const fs::path parent = fs::path(destination).parent_path();
  const std::string directory = parent.empty() ? "." : parent.string();
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) return;
  GIntBig free_bytes = VSIGetDiskFreeSpace(directory.c_str());
  if (const std::string fault = fault_switch("QTMV_FAULT_DISK_FREE_BYTES"); !fault.empty()) {
    free_bytes = static_cast<GIntBig>(std::strtoll(fault.c_str(), nullptr, 10));
  }
  if (free_bytes < 0 || size.bytes <= static_cast<std::uint64_t>(free_bytes)) return;
  throw WriteError("'" + destination + "': the " + kind + " takes about " + format_bytes(double(size.bytes)) +
                   (kind == "raster" ? " uncompressed" : "") + " (" + size.what + ") and '" + directory + "' has " +
                   format_bytes(double(free_bytes)) + " free: choose " + size.smaller +
                   "; for an output that compresses well or is sparse, add --config CHECK_DISK_FREE_SPACE NO");
}

}  // namespace qtmv::write
