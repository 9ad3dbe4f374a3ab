// The sources of a read (GDALRasterize's opening): the dataset opened by name, and the layers to
// read from it: the -sql result, the -l layers (several: composite sites), or the first.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include "gdal/error_capture.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

/// A layer to read and the name messages give it.
struct SourceLayer {
  OGRLayer* layer;
  std::string name;
};

/// The dataset opened for reading and its layers to read, in order.
struct OgrSource {
  std::string name;  ///< as given: a path or /vsi* path
  GDALDatasetUniquePtr dataset;
  std::shared_ptr<OGRLayer> sql_result;  ///< -sql's result set, released through the dataset
  std::vector<SourceLayer> layers;

  /// "'F', layer 'L'" or "'F', layers 'L1', 'L2'": where the read's summary says it read.
  std::string describe() const;
  /// Whether `name` is a regular file on disk (not /vsi*, a directory or a connection string):
  /// one that other GDAL datasets may open again and read beside this one. `bytes` (may be null)
  /// gets its size.
  bool plain_file(std::uint64_t* bytes = nullptr) const;
};

/// `dataset_name` opened by GDAL as a vector dataset, read-only, with the driver's open options
/// (-oo NAME=VALUE), by one of `drivers` (null-terminated; null: any); null when it does not open.
GDALDatasetUniquePtr open_vector(const std::string& dataset_name, const std::vector<std::string>& open_options,
                                 const char* const* drivers = nullptr);

/// Opens `dataset_name` with options.open_options and finds its layers (options.sql,
/// options.layers). The open's warnings go to options.messages; GDAL's messages are caught by
/// `errors`. Throws ReadError: not a file or directory, unreadable, -sql failed, no such layer
/// (the message lists the layers), no layer.
OgrSource open_source(const std::string& dataset_name, const ReadOptions& options, gdal::ErrorCapture& errors);

}  // namespace qtmv::sites
