#include "sites/feature_count.hpp"

#include <cpl_string.h>
#include <cpl_vsi.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "gdal/error_capture.hpp"

namespace qtmv::sites {

namespace {

/// Counts the features of layer `layer_name` of `dataset_name` opened anew (-1 when it cannot).
GIntBig count_on_own_handle(const std::string& dataset_name, const std::vector<std::string>& open_options,
                            const std::string& layer_name, const std::string& where) {
  gdal::ErrorCapture quiet;  // this thread's GDAL messages: the reading reports its own
  const GDALDatasetUniquePtr dataset = open_vector(dataset_name, open_options);
  OGRLayer* const layer = dataset ? dataset->GetLayerByName(layer_name.c_str()) : nullptr;
  if (!layer || (!where.empty() && layer->SetAttributeFilter(where.c_str()) != OGRERR_NONE)) return -1;
  return layer->GetFeatureCount(FALSE);
}

/// The rows of the CSV file `path` guessed from its size and its first rows' mean length (its
/// header line taken off); -1 when it is not a file or too short to tell.
GIntBig csv_rows_guess(const std::string& path) {
  constexpr std::size_t kSample = std::size_t{1} << 20;  // the first rows read (bytes)
  VSIStatBufL stat;
  if (VSIStatL(path.c_str(), &stat) != 0 || !VSI_ISREG(stat.st_mode) || stat.st_size <= 0) return -1;
  VSILFILE* file = VSIFOpenL(path.c_str(), "rb");
  if (!file) return -1;
  std::vector<char> bytes(std::min<std::size_t>(kSample, static_cast<std::size_t>(stat.st_size)));
  const std::size_t got = VSIFReadL(bytes.data(), 1, bytes.size(), file);
  VSIFCloseL(file);
  std::size_t lines = 0, end = 0;  // whole lines in the sample, and their bytes
  for (std::size_t k = 0; k < got; ++k) {
    if (bytes[k] == '\n') ++lines, end = k + 1;
  }
  if (got == static_cast<std::size_t>(stat.st_size) && end < got) ++lines, end = got;  // the last, unended
  if (lines < 2) return lines == 1 ? 0 : -1;
  const double per_line = static_cast<double>(end) / static_cast<double>(lines);
  return std::max<GIntBig>(0, static_cast<GIntBig>(static_cast<double>(stat.st_size) / per_line + 0.5) - 1);
}

}  // namespace

std::uint64_t feature_count_guess(const std::string& source, const SourceOptions& options) {
  if (!options.where.empty() || !options.sql.empty()) return 0;
  try {
    gdal::ErrorCapture quiet;  // a source that cannot be read is the read's to report
    const GDALDatasetUniquePtr dataset = open_vector(source, options.open_options);
    if (!dataset || dataset->GetLayerCount() == 0) return 0;
    std::vector<OGRLayer*> layers;
    if (options.layers.empty()) layers.push_back(dataset->GetLayer(0));
    for (const std::string& name : options.layers) layers.push_back(dataset->GetLayerByName(name.c_str()));
    const bool csv = dataset->GetDriver() && EQUAL(dataset->GetDriver()->GetDescription(), "CSV");
    std::uint64_t total = 0;
    for (OGRLayer* layer : layers) {
      if (!layer) return 0;
      GIntBig n = layer->TestCapability(OLCFastFeatureCount) ? layer->GetFeatureCount(FALSE) : -1;
      if (n < 0 && csv && layers.size() == 1) n = csv_rows_guess(source);  // the file is the layer
      if (n < 0) return 0;
      total += static_cast<std::uint64_t>(n);
    }
    return total;
  } catch (...) {
    return 0;
  }
}

FeatureCount::FeatureCount(const OgrSource& source, std::size_t layer_number, const ReadOptions& options,
                           int threads) {
  OGRLayer* const layer = source.layers[layer_number].layer;
  VSIStatBufL stat;
  const bool beside = threads > 1 && !layer->TestCapability(OLCFastFeatureCount) && options.sql.empty() &&
                      source.name.rfind("/vsi", 0) != 0 && VSIStatL(source.name.c_str(), &stat) == 0 &&
                      VSI_ISREG(stat.st_mode);
  if (!beside) {
    count_ = layer->GetFeatureCount(FALSE);
    return;
  }
  counting_ = std::async(std::launch::async, count_on_own_handle, source.name, options.open_options,
                         std::string(layer->GetName()), options.where);
}

FeatureCount::~FeatureCount() {
  if (counting_.valid()) counting_.wait();
}

GIntBig FeatureCount::wait() {
  if (counting_.valid()) counting_.wait();
  return get();
}

GIntBig FeatureCount::get() {
  if (counting_.valid() && counting_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
    try {
      count_ = counting_.get();
    } catch (...) {  // no count: the progress stays at the layer's start
      count_ = -1;
    }
  }
  return count_;
}

}  // namespace qtmv::sites
