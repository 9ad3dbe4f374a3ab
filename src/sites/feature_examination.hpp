// The features of a layer read in chunks: GDAL reads them on one thread (add); their parts,
// coordinate checks, transformation to lon/lat and polygon validity are found on all threads,
// a block of features at a time (examine_block), for the layer's reader to report and make into
// sites in feature order: the same messages and sites whatever the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <ogr_feature.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>

#include "gdal/error_capture.hpp"
#include "sites/feature_parts.hpp"
#include "sites/lonlat_transform.hpp"
#include "sites/polygon_validity.hpp"

namespace qtmv::sites {

/// Bounds (in the source CRS's units) beyond which coordinates are not handed to PROJ.
struct CoordinateRange {
  double limit_x = 0, limit_y = 0;
  std::string describe;  // for messages
};

CoordinateRange coordinate_range(const OGRSpatialReference& srs);

/// A feature read: what the checks on all threads found of it (examine_block), for the reader to
/// report and build in feature order.
struct PendingFeature {
  GIntBig fid = 0;
  OGRFeatureUniquePtr feature;  ///< its attributes
  std::unique_ptr<OGRGeometry> geometry;
  std::size_t vertices = 0;     ///< point_count of its geometry (the blocks' and chunks' size)
  /// Found before its polygons' validity is settled (reported before their warning).
  Skip skip = Skip::none;
  std::string skip_reason;
  std::optional<PolygonProblem> problem;  ///< of its polygons, as the source gives them
  /// Found by to_lonlat (reported after the validity's warning, as the source is read): a failed
  /// transformation is done again in feature order with the layer's own transformation, whose
  /// messages count the failures before.
  Skip late_skip = Skip::none;
  std::string late_reason;
  std::uint32_t block = 0;      ///< the block holding its parts
  std::size_t part_begin = 0, part_end = 0;  ///< its parts, in its block's parts
};

/// What examine_block needs of the layer: the checks, and the transformations to lon/lat.
struct Examination {
  const CoordinateRange& range;
  const PolygonValidityCheck& validity;
  ThreadTransforms& transforms;
};

/// A chunk's features, read on one thread, then examined on all threads in blocks.
class FeatureChunk {
 public:
  /// Adds `feature` (read just now): its geometry taken, or a skip found while reading
  /// (unreadable: a failure `errors` caught since its last take; no geometry).
  void add(OGRFeatureUniquePtr feature, gdal::ErrorCapture& errors);
  /// Whether the chunk holds enough work for every thread (memory bounded).
  bool full() const;
  /// The features read, in reading order.
  std::size_t size() const { return count_; }
  /// Their geometries' vertices (a point is one).
  std::size_t vertex_count() const { return vertices_; }
  PendingFeature& feature(std::size_t k) { return features_[k]; }
  /// The blocks the features are examined in (each a unit of work).
  std::size_t block_count() const { return block_count_; }
  /// Examines block `b`'s features (examine): called on any thread, once per block.
  void examine_block(std::size_t b, const Examination& examination);
  /// The parts of block `b` (coordinates in lon/lat once examined).
  FeatureParts& block_parts(std::size_t b) { return blocks_[b].parts; }
  /// A place for a feature's parts that are not its block's (repaired by -makevalid, or
  /// transformed again): kept until the chunk is cleared.
  FeatureParts& own_parts();
  /// Forgets the features (their memory kept for the next chunk).
  void clear();
  /// Destroys block `b`'s features and geometries (any thread, once per block; before clear):
  /// for features made on other threads, whose memory a thread of the team gives back beside
  /// the others instead of the reading thread one by one.
  void release_block(std::size_t b);

 private:
  /// Destroys features [first, last) and their geometries.
  void release(std::size_t first, std::size_t last);

  struct Block {
    std::size_t first = 0, last = 0;  // features
    std::size_t vertices = 0;
    FeatureParts parts;
  };
  std::vector<PendingFeature> features_;
  std::size_t count_ = 0, vertices_ = 0;
  std::vector<Block> blocks_;
  std::size_t block_count_ = 0;
  std::deque<FeatureParts> own_parts_;
};

}  // namespace qtmv::sites
