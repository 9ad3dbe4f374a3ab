// The features of a layer read in chunks: GDAL reads them on one thread; their parts, coordinate
// checks and polygon validity are found on all threads (examine), for the layer's reader to
// report and make into sites in feature order: the same messages whatever the thread count.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogr_feature.h>

#include "gdal/error_capture.hpp"
#include "sites/feature_parts.hpp"
#include "sites/polygon_validity.hpp"

namespace qtmv::sites {

/// Bounds (in the source CRS's units) beyond which coordinates are not handed to PROJ.
struct CoordinateRange {
  double limit_x = 0, limit_y = 0;
  std::string describe;  // for messages
};

CoordinateRange coordinate_range(const OGRSpatialReference& srs);

/// "(x, y)" with 15 significant digits, for messages.
std::string format_coordinate(double x, double y);

/// A feature read and its geometry taken: what the checks on all threads found of it (examine),
/// for the reader to report and build in feature order.
struct PendingFeature {
  enum class Skip { none, unreadable, empty, type, coordinate };
  GIntBig fid = 0;
  OGRFeatureUniquePtr feature;  ///< its attributes
  std::unique_ptr<OGRGeometry> geometry;
  FeatureParts parts;
  Skip skip = Skip::none;
  std::string skip_reason;
  std::optional<PolygonProblem> problem;  ///< of its polygons, as the source gives them
};

/// A pending feature's parts, coordinate checks and polygon validity, or why it is skipped.
/// Changes only `pending`: several threads examine a chunk's features at once.
void examine(PendingFeature& pending, const CoordinateRange& range, const PolygonValidityCheck& validity);

/// Features read before they are examined on all threads.
class FeatureChunk {
 public:
  /// Adds `feature` (read just now): its geometry taken and linearised, or a skip found while
  /// reading (unreadable: a failure `errors` caught since its last take; empty).
  void add(OGRFeatureUniquePtr feature, gdal::ErrorCapture& errors);
  /// Whether the chunk holds enough work for every thread (memory bounded).
  bool full() const;
  /// Examines every feature on `threads` threads (examine).
  void examine_all(const CoordinateRange& range, const PolygonValidityCheck& validity, int threads);
  /// The features in reading order.
  std::vector<PendingFeature>& features() { return features_; }
  void clear();

 private:
  std::vector<PendingFeature> features_;
  std::size_t vertices_ = 0;
};

}  // namespace qtmv::sites
