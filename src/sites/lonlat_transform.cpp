#include "sites/lonlat_transform.hpp"

#include <cmath>
#include <sstream>

#include "common/openmp_threads.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

std::string format_coordinate(double x, double y) {
  std::ostringstream s;
  s.precision(15);
  s << "(" << x << ", " << y << ")";
  return s.str();
}

Skip to_lonlat(grid::LonLat* points, std::size_t count, OGRCoordinateTransformation* transform,
               gdal::ErrorCapture& errors, LonLatScratch& scratch, std::string& reason) {
  if (transform) {
    scratch.x.resize(count);
    scratch.y.resize(count);
    scratch.ok.assign(count, FALSE);
    for (std::size_t k = 0; k < count; ++k) {
      scratch.x[k] = points[k].lon;
      scratch.y[k] = points[k].lat;
    }
    errors.take();  // the messages of this transformation only
    transform->Transform(static_cast<int>(count), scratch.x.data(), scratch.y.data(), nullptr, scratch.ok.data());
    for (std::size_t k = 0; k < count; ++k) {
      if (!scratch.ok[k] || !std::isfinite(scratch.x[k]) || !std::isfinite(scratch.y[k])) {
        reason = with_gdal_message("coordinate " + format_coordinate(points[k].lon, points[k].lat) +
                                       " fails to transform to WGS84",
                                   errors.take());
        return Skip::transform;
      }
    }
  }
  for (std::size_t k = 0; k < count; ++k) {
    const double lon = transform ? scratch.x[k] : points[k].lon;
    double lat = transform ? scratch.y[k] : points[k].lat;
    if (std::fabs(lat) > 90.0) {
      if (std::fabs(lat) > 90.0 + 1e-9) {
        reason = std::string("latitude beyond +-90") + (transform ? " after transformation" : "") + " at " +
                 format_coordinate(lon, lat);
        return Skip::coordinate;
      }
      lat = lat > 0 ? 90.0 : -90.0;  // rounding in the transformation
    }
    points[k] = {lon, lat};
  }
  return Skip::none;
}

ThreadTransforms::ThreadTransforms(const OGRCoordinateTransformation* layer, int threads)
    : any_(layer != nullptr), copies_(layer ? static_cast<std::size_t>(threads) : 0, nullptr),
      tried_(copies_.size(), 0) {
  if (layer) {
    gdal::ErrorCapture quiet;  // without copies, the reader's thread transforms the features
    original_ = layer->Clone();
  }
}

// Deleted, not given to DestroyCT: OGR would keep them for the next transformation made between
// the same CRSs, with the failures they have counted (the messages stop after 20), in place of
// the layer's, which reported the failures.
ThreadTransforms::~ThreadTransforms() {
  for (OGRCoordinateTransformation* copy : copies_) delete copy;
  delete original_;
}

OGRCoordinateTransformation* ThreadTransforms::of_this_thread() {
  if (!original_) return nullptr;
  const auto k = static_cast<std::size_t>(thread_index());
  if (!tried_[k]) {
    const std::lock_guard<std::mutex> lock(mutex_);
    gdal::ErrorCapture quiet;
    copies_[k] = original_->Clone();
    tried_[k] = 1;
  }
  return copies_[k];
}

}  // namespace qtmv::sites
