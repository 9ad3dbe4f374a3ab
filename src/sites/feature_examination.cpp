#include "sites/feature_examination.hpp"

#include <cmath>
#include <cstdint>
#include <utility>

#include "sites/site_options.hpp"

namespace qtmv::sites {

namespace {

/// Features read in a chunk: work for every thread between two steps of the read (a step's
/// threads meet at its end), memory bounded (a few chunks are held at once).
constexpr std::size_t kChunkFeatures = std::size_t{1} << 16;
constexpr std::size_t kChunkVertices = std::size_t{1} << 20;
/// Features examined as one unit of work: worth a thread, and many of them per chunk.
constexpr std::size_t kBlockFeatures = 1024;
constexpr std::size_t kBlockVertices = std::size_t{1} << 16;

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

namespace {

/// Finds what `pending` is made of and whether it is read (its parts appended to `parts`, the
/// block's), on any thread: changes only `pending` and `parts`.
void examine(PendingFeature& pending, FeatureParts& parts, const Examination& examination,
             OGRCoordinateTransformation* transform, gdal::ErrorCapture& errors, LonLatScratch& scratch) {
  const std::size_t part_begin = parts.parts.size(), point_begin = parts.points.size();
  pending.part_begin = pending.part_end = part_begin;
  if (pending.skip != Skip::none) return;  // found while reading
  if (pending.geometry->IsEmpty()) {
    pending.skip = Skip::empty;
    pending.skip_reason = "empty geometry";
    return;
  }
  if (pending.geometry->hasCurveGeometry()) {
    std::unique_ptr<OGRGeometry> linear(pending.geometry->getLinearGeometry());
    if (!linear) {
      pending.skip = Skip::type;
      pending.skip_reason = std::string("cannot linearise ") + OGRGeometryTypeToName(pending.geometry->getGeometryType());
      return;
    }
    pending.geometry = std::move(linear);
  }
  parts.polygons = 0;
  if (!gather_parts(*pending.geometry, parts, pending.skip_reason)) {
    parts.truncate(part_begin, point_begin);
    pending.skip = Skip::type;
    return;
  }
  if (parts.parts.size() == part_begin) {
    pending.skip = Skip::empty;
    pending.skip_reason = "empty geometry";
    return;
  }
  // Checked before PROJ sees them (GDAL 3.6 hangs on EPSG:3857 coordinates near +-1e20).
  const CoordinateRange& range = examination.range;
  for (std::size_t k = point_begin; k < parts.points.size(); ++k) {
    const double x = parts.points[k].lon, y = parts.points[k].lat;
    if (!std::isfinite(x) || !std::isfinite(y)) {
      pending.skip = Skip::coordinate;
      pending.skip_reason = "NaN or infinite coordinate " + format_coordinate(x, y);
    } else if (std::fabs(x) > range.limit_x || std::fabs(y) > range.limit_y) {
      pending.skip = Skip::coordinate;
      pending.skip_reason = "coordinate " + format_coordinate(x, y) + " beyond " + range.describe + " of its CRS";
    }
    if (pending.skip != Skip::none) {
      parts.truncate(part_begin, point_begin);
      return;
    }
  }
  pending.problem = examination.validity.problem_of(*pending.geometry);
  pending.part_end = parts.parts.size();
  if (examination.transforms.any() && !transform) {
    pending.late_skip = Skip::transform;  // no copy of the transformation here: the reader's thread does it
    return;
  }
  pending.late_skip = to_lonlat(parts.points.data() + point_begin, parts.points.size() - point_begin, transform,
                                errors, scratch, pending.late_reason);
}

}  // namespace

void FeatureChunk::add(OGRFeatureUniquePtr feature, gdal::ErrorCapture& errors) {
  if (count_ == features_.size()) features_.emplace_back();
  PendingFeature& pending = features_[count_++];
  pending.fid = feature->GetFID();
  pending.vertices = 0;
  pending.skip = pending.late_skip = Skip::none;
  pending.skip_reason.clear();
  pending.late_reason.clear();
  pending.problem.reset();
  // A driver that cannot decode one feature (a corrupt geometry blob, say) reports it while
  // reading that feature: skip it with GDAL's reason instead of failing the whole read.
  if (errors.failed()) {
    pending.skip = Skip::unreadable;
    pending.skip_reason = "unreadable feature (GDAL: " + errors.take() + ")";
  } else {
    pending.geometry.reset(feature->StealGeometry());
    if (!pending.geometry) {
      pending.skip = Skip::empty;
      pending.skip_reason = "empty geometry";
    } else {
      pending.vertices = point_count(*pending.geometry);
    }
  }
  pending.feature = std::move(feature);
  vertices_ += pending.vertices;
  // Blocks of about equal work, each examined by one thread.
  if (block_count_ == 0 || blocks_[block_count_ - 1].last - blocks_[block_count_ - 1].first >= kBlockFeatures ||
      blocks_[block_count_ - 1].vertices >= kBlockVertices) {
    if (block_count_ == blocks_.size()) blocks_.emplace_back();
    Block& block = blocks_[block_count_++];
    block.first = block.last = count_ - 1;
    block.vertices = 0;
  }
  Block& block = blocks_[block_count_ - 1];
  block.last = count_;
  block.vertices += pending.vertices;
  pending.block = static_cast<std::uint32_t>(block_count_ - 1);
}

bool FeatureChunk::full() const { return count_ >= kChunkFeatures || vertices_ >= kChunkVertices; }

void FeatureChunk::examine_block(std::size_t b, const Examination& examination) {
  Block& block = blocks_[b];
  block.parts.clear();
  // This thread's GDAL messages (a transformation's, a curve's) kept from the other handlers: a
  // failed transformation is reported in feature order by the reader's thread.
  gdal::ErrorCapture errors;
  LonLatScratch scratch;
  OGRCoordinateTransformation* const transform = examination.transforms.of_this_thread();
  for (std::size_t k = block.first; k < block.last; ++k) {
    examine(features_[k], block.parts, examination, transform, errors, scratch);
  }
}

FeatureParts& FeatureChunk::own_parts() { return own_parts_.emplace_back(); }

void FeatureChunk::release(std::size_t first, std::size_t last) {
  for (std::size_t k = first; k < last; ++k) {
    features_[k].feature.reset();
    features_[k].geometry.reset();
  }
}

void FeatureChunk::release_block(std::size_t b) { release(blocks_[b].first, blocks_[b].last); }

void FeatureChunk::clear() {
  release(0, count_);
  count_ = vertices_ = block_count_ = 0;
  own_parts_.clear();
}

}  // namespace qtmv::sites
