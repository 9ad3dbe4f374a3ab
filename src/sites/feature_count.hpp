// A layer's feature count, for the read's progress. GDAL counts some layers only by reading them
// through (a CSV: 0.8 s of a 5 s read of a million rows, on the reading thread before its first
// feature); such a layer of a file is counted beside the reading instead, on a handle of its own.
#pragma once

#include <cstdint>
#include <future>
#include <string>

#include <ogrsf_frmts.h>

#include "sites/ogr_source.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

class FeatureCount {
 public:
  /// Not counted (-1): a read whose progress comes from elsewhere.
  FeatureCount() = default;
  /// Counts layer `layer_number` of `source` (its -where set): at once when the driver knows
  /// the count cheaply, when the read has one thread, or when the layer is a -sql result or not
  /// in a file; else beside the reading.
  FeatureCount(const OgrSource& source, std::size_t layer_number, const ReadOptions& options, int threads);
  /// Waits for a count begun beside the reading (it cannot be stopped).
  ~FeatureCount();
  FeatureCount(const FeatureCount&) = delete;
  FeatureCount& operator=(const FeatureCount&) = delete;

  /// The count; -1 while it is not known (yet: counted beside the reading; or at all: GDAL
  /// counts a CSV with -where only by reading it, which the progress is not worth).
  GIntBig get();
  /// The count, once a count begun beside the reading is done.
  GIntBig wait();

 private:
  GIntBig count_ = -1;
  std::future<GIntBig> counting_;
};

/// A quick guess of the features a read of `source` will see, made before the read (for -device
/// auto, which starts a GPU beside the read when the guess already shows it worth starting): the
/// driver's cheap counts of the layers read (-l, else the first; a GeoPackage's, a shapefile's),
/// or, for a CSV file, its size over the mean length of its first rows (within a few per cent for
/// rows alike). 0: no guess (-where or -sql, whose share is unknown; a source GDAL cannot open; a
/// layer of neither kind). Opens the source once, quietly; never throws.
std::uint64_t feature_count_guess(const std::string& source, const SourceOptions& options);

}  // namespace qtmv::sites
