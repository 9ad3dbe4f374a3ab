#include "sites/feature_examination.hpp"

#include <cmath>
#include <cstdint>
#include <sstream>
#include <utility>

#include "common/first_exception.hpp"

namespace qtmv::sites {

namespace {

/// Features read before they are examined on all threads: work for every thread, memory bounded.
constexpr std::size_t kChunkFeatures = 1024;
constexpr std::size_t kChunkVertices = std::size_t{1} << 20;

}  // namespace

CoordinateRange coordinate_range(const OGRSpatialReference& srs) {
  CoordinateRange range;
  if (srs.IsGeographic()) {
    // Degrees, wherever latitude sits: a longitude may go round more than once when unwrapped.
    const double degrees_per_unit = srs.GetAngularUnits(nullptr) / (M_PI / 180.0);
    range.limit_x = range.limit_y = 540.0 / degrees_per_unit;
    range.describe = "+-540 degrees";
  } else {
    // Projected, geocentric or other: 1e8 metres is 2.5 times round the Earth.
    const double metres_per_unit = srs.GetLinearUnits(nullptr);
    range.limit_x = range.limit_y = 1e8 / (metres_per_unit > 0 ? metres_per_unit : 1.0);
    range.describe = "+-1e8 metres";
  }
  return range;
}

std::string format_coordinate(double x, double y) {
  std::ostringstream s;
  s.precision(15);
  s << "(" << x << ", " << y << ")";
  return s.str();
}

void examine(PendingFeature& pending, const CoordinateRange& range, const PolygonValidityCheck& validity) {
  if (pending.skip != PendingFeature::Skip::none) return;  // found while reading
  if (!gather_parts(*pending.geometry, pending.parts, pending.skip_reason)) {
    pending.skip = PendingFeature::Skip::type;
    return;
  }
  if (pending.parts.parts.empty()) {
    pending.skip = PendingFeature::Skip::empty;
    pending.skip_reason = "empty geometry";
    return;
  }
  // Checked before PROJ sees them (GDAL 3.6 hangs on EPSG:3857 coordinates near +-1e20).
  for (std::size_t k = 0; k < pending.parts.x.size(); ++k) {
    const double x = pending.parts.x[k], y = pending.parts.y[k];
    if (!std::isfinite(x) || !std::isfinite(y)) {
      pending.skip = PendingFeature::Skip::coordinate;
      pending.skip_reason = "NaN or infinite coordinate " + format_coordinate(x, y);
      return;
    }
    if (std::fabs(x) > range.limit_x || std::fabs(y) > range.limit_y) {
      pending.skip = PendingFeature::Skip::coordinate;
      pending.skip_reason = "coordinate " + format_coordinate(x, y) + " beyond " + range.describe + " of its CRS";
      return;
    }
  }
  pending.problem = validity.problem_of(*pending.geometry);
}

void FeatureChunk::add(OGRFeatureUniquePtr feature, gdal::ErrorCapture& errors) {
  PendingFeature& pending = features_.emplace_back();
  pending.fid = feature->GetFID();
  // A driver that cannot decode one feature (a corrupt geometry blob, say) reports it while
  // reading that feature: skip it with GDAL's reason instead of failing the whole read.
  if (errors.failed()) {
    pending.skip = PendingFeature::Skip::unreadable;
    pending.skip_reason = "unreadable feature (GDAL: " + errors.take() + ")";
  } else {
    pending.geometry.reset(feature->StealGeometry());
    if (!pending.geometry || pending.geometry->IsEmpty()) {
      pending.skip = PendingFeature::Skip::empty;
      pending.skip_reason = "empty geometry";
    } else if (pending.geometry->hasCurveGeometry()) {
      pending.geometry.reset(pending.geometry->getLinearGeometry());
    }
  }
  pending.feature = std::move(feature);
  if (pending.geometry) vertices_ += point_count(*pending.geometry);
}

bool FeatureChunk::full() const { return features_.size() >= kChunkFeatures || vertices_ >= kChunkVertices; }

void FeatureChunk::examine_all(const CoordinateRange& range, const PolygonValidityCheck& validity, int threads) {
  const auto n = static_cast<std::int64_t>(features_.size());
  FirstException failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) {
    failure.run([&] { examine(features_[static_cast<std::size_t>(k)], range, validity); });
  }
  failure.rethrow();
}

void FeatureChunk::clear() {
  features_.clear();
  vertices_ = 0;
}

}  // namespace qtmv::sites
