// A raster's strips of rows filled with the bands' values: each pixel's cell, the labels of the
// strip's cells asked of a CellLabelSource (only those the bands need), and the values, on all
// cores (raster_writer.hpp says what the layouts and the bands hold).
#pragma once

#include <gdal.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "write/cell_labels.hpp"
#include "write/raster_writer.hpp"

namespace qtmv::write {

/// What a strip filler is given: the raster's grid, bands and type, and the labels' source.
struct StripSetup {
  int level = 0;
  RasterGrid::Layout layout = RasterGrid::Layout::qtm;
  RasterSize size;
  std::vector<RasterBand> bands;  ///< in the raster's order
  GDALDataType type = GDT_Float32;
  double nodata = -1;
  const CellLabelSource* source = nullptr;
  const std::vector<std::int64_t>* fid_of = nullptr;  ///< each site id's FID
  int threads = 1;
};

/// Seconds spent filling strips, by step.
struct StripTimes {
  double cells = 0;   ///< the pixels' cells and the strip's codes
  double labels = 0;  ///< asking the source for the strip's labels
  double values = 0;  ///< the bands' values
};

class StripFiller {
 public:
  explicit StripFiller(const StripSetup& setup);
  ~StripFiller();
  StripFiller(const StripFiller&) = delete;
  StripFiller& operator=(const StripFiller&) = delete;

  /// Fills rows [y0, y0 + rows) of every band into `buffer`: the k-th band of setup.bands from
  /// value k * width * rows on, row by row, values of setup.type. Problems (a site id outside the
  /// table, a distance the type cannot hold) are kept for check(); the source's exceptions pass.
  void fill(int y0, int rows, void* buffer);
  /// Throws WriteError naming `path`, the band and the value for a problem the fills found.
  void check(const std::string& path) const;
  /// Per site id: 1 when some pixel filled so far holds the site, else 0.
  std::vector<std::uint8_t> site_seen() const;
  const StripTimes& times() const;

  /// Bytes a strip's pixel takes at most in the filler (for the lon/lat layout the labels of up
  /// to four cells a pixel, and room for two codes a pixel; one cell's labels for the QTM-coded
  /// raster), beside the pixel's values.
  static std::uint64_t bytes_per_pixel(RasterGrid::Layout layout, const std::vector<RasterBand>& bands);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace qtmv::write
