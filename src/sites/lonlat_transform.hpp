// Coordinates to WGS84 lon/lat: a feature's points transformed from its layer's CRS (on any
// thread, each with its own copy of the layer's transformation) and their latitudes checked.
#pragma once

#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <ogr_spatialref.h>

#include "gdal/error_capture.hpp"
#include "grid/qtm_geometry.hpp"

namespace qtmv::sites {

/// "(x, y)" with 15 significant digits, for messages.
std::string format_coordinate(double x, double y);

/// Why a feature is skipped, and which count of the summary it adds to.
enum class Skip { none, unreadable, empty, type, coordinate, transform };

/// Arrays to_lonlat reuses from feature to feature.
struct LonLatScratch {
  std::vector<double> x, y;
  std::vector<int> ok;
};

/// Turns `count` points (x in lon, y in lat, in the source CRS) into WGS84 lon/lat degrees in
/// place: transformed by `transform` (when not null), then latitudes checked, a rounding beyond
/// +-90 set to +-90. Returns Skip::none, or Skip::transform / Skip::coordinate with `reason`
/// (the points are then left as they were given when the transformation failed). GDAL's messages
/// of the transformation are taken from `errors`, a capture on the calling thread.
Skip to_lonlat(grid::LonLat* points, std::size_t count, OGRCoordinateTransformation* transform,
               gdal::ErrorCapture& errors, LonLatScratch& scratch, std::string& reason);

/// Gives a transformation back to OGR (DestroyCT), which may keep it for the next one between the
/// same CRSs.
struct DestroyTransform {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
/// A transformation made by OGRCreateCoordinateTransformation, owned.
using OwnedTransform = std::unique_ptr<OGRCoordinateTransformation, DestroyTransform>;

/// One copy of a layer's transformation to WGS84 per thread, made on first use: OGR's
/// transformations (and the CRSs they hold) are not for several threads at once, so the copies
/// are made one at a time from a copy of their own.
class ThreadTransforms {
 public:
  /// `layer`: the layer's transformation (null: none), copied here; `threads`: the team's size
  /// at most.
  ThreadTransforms(const OGRCoordinateTransformation* layer, int threads);
  ~ThreadTransforms();
  ThreadTransforms(const ThreadTransforms&) = delete;
  ThreadTransforms& operator=(const ThreadTransforms&) = delete;
  /// Whether there is a transformation at all.
  bool any() const { return any_; }
  /// The calling thread's copy (of an OpenMP team); null when there is none, or OGR cannot copy it.
  OGRCoordinateTransformation* of_this_thread();

 private:
  bool any_;
  OGRCoordinateTransformation* original_ = nullptr;  // the copies' source, used by none
  std::mutex mutex_;  // taken once per thread and layer, to make its copy
  std::vector<OGRCoordinateTransformation*> copies_;
  std::vector<char> tried_;
};

}  // namespace qtmv::sites
