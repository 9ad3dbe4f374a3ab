#include "sites/feature_count.hpp"

#include <cpl_string.h>
#include <cpl_vsi.h>

#include <chrono>
#include <vector>

#include "gdal/error_capture.hpp"

namespace qtmv::sites {

namespace {

/// Counts the features of layer `layer_name` of `dataset_name` opened anew (-1 when it cannot).
GIntBig count_on_own_handle(const std::string& dataset_name, const std::vector<std::string>& open_options,
                            const std::string& layer_name, const std::string& where) {
  gdal::ErrorCapture quiet;  // this thread's GDAL messages: the reading reports its own
  CPLStringList options;
  for (const std::string& option : open_options) options.AddString(option.c_str());
  GDALDatasetUniquePtr dataset(
      GDALDataset::Open(dataset_name.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, options.List()));
  OGRLayer* const layer = dataset ? dataset->GetLayerByName(layer_name.c_str()) : nullptr;
  if (!layer || (!where.empty() && layer->SetAttributeFilter(where.c_str()) != OGRERR_NONE)) return -1;
  return layer->GetFeatureCount(FALSE);
}

}  // namespace

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
