#include "sites/layer_reader.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "sites/feature_examination.hpp"
#include "sites/feature_parts.hpp"
#include "sites/polygon_validity.hpp"

namespace qtmv::sites {

namespace {

struct OgrDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};

/// A layer's CRS, the transformation from it to WGS84 (none when it is WGS84 in lon/lat order),
/// and the range its coordinates are checked against.
struct LayerCrs {
  OGRSpatialReference source;
  std::unique_ptr<OGRCoordinateTransformation, OgrDeleter> transform;
  CoordinateRange range;
};

/// The CRS of `layer`: options.source_srs, the layer's, or (with a warning) WGS84.
LayerCrs layer_crs(OGRLayer& layer, const std::string& where_from, const ReadOptions& options,
                   gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84) {
  LayerCrs crs;
  OGRSpatialReference& source = crs.source;
  if (!options.source_srs.empty()) {
    errors.take();
    if (source.SetFromUserInput(options.source_srs.c_str()) != OGRERR_NONE) {
      throw ReadError(with_gdal_message("-s_srs: cannot read '" + options.source_srs + "'", errors.take()));
    }
    source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  } else if (const OGRSpatialReference* layer_srs = layer.GetSpatialRef()) {
    source = *layer_srs;  // keeps the layer's data axis order
  } else {
    tell(options.messages, Severity::warning,
         where_from + ": the layer has no CRS; its coordinates are taken as EPSG:4326 (WGS84 lon/lat)");
    source = wgs84;
  }
  if (!(source.IsSame(&wgs84) && source.GetDataAxisToSRSAxisMapping() == wgs84.GetDataAxisToSRSAxisMapping())) {
    errors.take();
    crs.transform.reset(OGRCreateCoordinateTransformation(&source, &wgs84));
    if (!crs.transform) {
      throw ReadError(with_gdal_message(where_from + ": no transformation from its CRS (" +
                                            std::string(source.GetName() ? source.GetName() : "?") + ") to WGS84",
                                        errors.take()));
    }
  }
  crs.range = coordinate_range(source);
  return crs;
}

/// GDAL opens a shapefile without its .dbf silently, with no fields: say the attributes are gone.
void warn_missing_dbf(const OgrSource& source, const std::string& where_from, const ReadOptions& options) {
  const std::string& dataset_name = source.name;
  if (EQUAL(source.dataset->GetDriverName(), "ESRI Shapefile") && EQUAL(CPLGetExtension(dataset_name.c_str()), "shp")) {
    VSIStatBufL dbf;
    if (VSIStatL(CPLResetExtension(dataset_name.c_str(), "dbf"), &dbf) != 0 &&
        VSIStatL(CPLResetExtension(dataset_name.c_str(), "DBF"), &dbf) != 0) {
      tell(options.messages, Severity::warning, where_from + ": no .dbf beside the .shp; the sites have no attributes");
    }
  }
}

/// The summary's count of the features skipped for `why`.
std::uint64_t& skip_counter(ReadSummary& summary, PendingFeature::Skip why) {
  switch (why) {
    case PendingFeature::Skip::unreadable: return summary.skipped_unreadable;
    case PendingFeature::Skip::type: return summary.skipped_type;
    case PendingFeature::Skip::coordinate: return summary.skipped_coordinate;
    default: return summary.skipped_empty;
  }
}

/// One layer's reading, its filter set: the per-layer state, from its CRS to its last batch.
class LayerReader {
 public:
  LayerReader(const OgrSource& source, std::size_t layer_number, std::string where_from, const ReadOptions& options,
              gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84, ReadTotals& totals);
  /// Reads the features, builds their sites, then says what the layer's reading found.
  void read();

 private:
  void read_features();
  void settle_chunk();
  void settle(PendingFeature& pending);
  bool to_lonlat(GIntBig fid, FeatureParts& parts);
  void skip(GIntBig fid, const std::string& reason, std::uint64_t& counter);
  void finish();

  const ReadOptions& options_;
  gdal::ErrorCapture& errors_;
  ReadTotals& totals_;
  ReadSummary& summary_;
  OGRLayer* const layer_;
  const std::size_t layer_number_, layer_count_;
  const std::string where_from_;
  const std::uint64_t features_before_, sites_before_, skipped_before_;
  const LayerCrs crs_;
  const std::uint32_t layer_index_;  // the layer's source in the site table
  PolygonValidityCheck validity_;
  const GIntBig feature_count_;
  // Features are read in chunks: GDAL reads them on this thread; their parts, coordinate checks
  // and polygon validity are found on all threads; then, in feature order, they are reported and
  // become sites: the same messages and sites whatever the thread count.
  FeatureChunk chunk_;
  SiteBatch batch_;
  std::vector<grid::LonLat> lonlat_;
  std::vector<int> transformed_ok_;
};

LayerReader::LayerReader(const OgrSource& source, std::size_t layer_number, std::string where_from,
                         const ReadOptions& options, gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84,
                         ReadTotals& totals)
    : options_(options),
      errors_(errors),
      totals_(totals),
      summary_(totals.out.summary),
      layer_(source.layers[layer_number].layer),
      layer_number_(layer_number),
      layer_count_(source.layers.size()),
      where_from_(std::move(where_from)),
      features_before_(summary_.features),
      sites_before_(summary_.sites),
      skipped_before_(summary_.skipped),
      crs_(layer_crs(*layer_, where_from_, options, errors, wgs84)),
      layer_index_(totals.out.table.add_source(layer_->GetLayerDefn(), source.name, source.layers[layer_number].name)),
      validity_(options, crs_.source, where_from_),
      feature_count_(layer_->GetFeatureCount(FALSE)),
      batch_(totals.builders, totals.out.geometry, totals.times) {}

void LayerReader::read() {
  read_features();
  finish();
}

void LayerReader::read_features() {
  errors_.take();
  layer_->ResetReading();
  for (OGRFeatureUniquePtr feature(layer_->GetNextFeature()); feature; feature.reset(layer_->GetNextFeature())) {
    ++summary_.features;
    if (options_.progress && feature_count_ > 0 && summary_.features % 256 == 0 &&
        !options_.progress((static_cast<double>(layer_number_) +
                            std::min(1.0, static_cast<double>(summary_.features - features_before_) / feature_count_)) /
                               static_cast<double>(layer_count_),
                           "reading sites")) {
      throw Interrupted();
    }
    chunk_.add(std::move(feature), errors_);
    if (chunk_.full()) settle_chunk();
  }
  settle_chunk();
  batch_.build();
}

void LayerReader::settle_chunk() {
  const auto examine_start = std::chrono::steady_clock::now();
  chunk_.examine_all(crs_.range, validity_, totals_.builders.threads());
  totals_.times.examined_s += seconds_since(examine_start);
  for (PendingFeature& pending : chunk_.features()) settle(pending);
  chunk_.clear();
}

/// Reports a pending feature, or makes it a site whose jobs wait in the batch.
void LayerReader::settle(PendingFeature& pending) {
  const GIntBig fid = pending.fid;
  if (pending.skip != PendingFeature::Skip::none) {
    skip(fid, pending.skip_reason, skip_counter(summary_, pending.skip));
    return;
  }
  FeatureParts& parts = pending.parts;
  std::unique_ptr<OGRGeometry>& geometry = pending.geometry;
  // Invalid polygons are named (or repaired, -makevalid) as the source gives them.
  if (validity_.settle(fid, geometry, pending.problem)) {
    parts = FeatureParts{};
    std::string reason;
    if (!gather_parts(*geometry, parts, reason) || parts.parts.empty()) {
      skip(fid, "nothing left after -makevalid", summary_.skipped_empty);
      return;
    }
  }
  if (!to_lonlat(fid, parts)) return;

  // --- one site, built with the next batch ---
  SiteRecord record;
  record.fid = fid;
  record.layer = layer_index_;
  for (const FeatureParts::Part& part : parts.parts) {
    record.kind |= part.kind == FeatureParts::kPoint ? kPointSite : part.kind == FeatureParts::kLine ? kLineSite
                                                                                                     : kPolygonSite;
  }
  record.attributes.reset(pending.feature.release());
  totals_.out.table.sites.push_back(std::move(record));
  ++summary_.sites;
  batch_.add(fid, std::move(lonlat_), std::move(parts.parts));
  lonlat_ = {};
  pending = PendingFeature{};  // its geometry's memory back before the next
  if (batch_.full()) batch_.build();
}

/// Transforms `parts` to WGS84 and puts them in lonlat_; false when the feature is skipped.
bool LayerReader::to_lonlat(GIntBig fid, FeatureParts& parts) {
  const auto& transform = crs_.transform;
  const std::size_t n_points = parts.x.size();
  bool usable = true;
  if (transform) {
    transformed_ok_.assign(n_points, FALSE);
    gdal::ErrorCapture transform_errors;
    const std::vector<double> x0 = parts.x, y0 = parts.y;
    transform->Transform(static_cast<int>(n_points), parts.x.data(), parts.y.data(), nullptr,
                         transformed_ok_.data());
    for (std::size_t k = 0; k < n_points && usable; ++k) {
      if (!transformed_ok_[k] || !std::isfinite(parts.x[k]) || !std::isfinite(parts.y[k])) {
        skip(fid, with_gdal_message("coordinate " + format_coordinate(x0[k], y0[k]) + " fails to transform to WGS84",
                                    transform_errors.take()),
             summary_.skipped_transform);
        usable = false;
      }
    }
    if (!usable) return false;
  }
  lonlat_.resize(n_points);
  for (std::size_t k = 0; k < n_points && usable; ++k) {
    double lat = parts.y[k];
    if (std::fabs(lat) > 90.0) {
      if (std::fabs(lat) > 90.0 + 1e-9) {
        skip(fid, std::string("latitude beyond +-90") + (transform ? " after transformation" : "") + " at " +
                      format_coordinate(parts.x[k], lat),
             summary_.skipped_coordinate);
        usable = false;
        break;
      }
      lat = lat > 0 ? 90.0 : -90.0;  // rounding in the transformation
    }
    lonlat_[k] = {parts.x[k], lat};
  }
  return usable;
}

// One warning a skipped feature, the first kMostListed of them; then a count (a CSV read without
// its coordinate columns would otherwise give a line per row).
void LayerReader::skip(GIntBig fid, const std::string& reason, std::uint64_t& counter) {
  const std::string message = where_from_ + ", FID " + std::to_string(fid) + ": " + reason;
  if (options_.strict) throw ReadError(message + " (-strict)");
  if (summary_.skipped < PolygonValidityCheck::kMostListed) tell(options_.messages, Severity::warning, message + "; feature skipped");
  ++summary_.skipped;
  ++counter;
}

void LayerReader::finish() {
  validity_.finish();
  if (summary_.skipped > PolygonValidityCheck::kMostListed) {
    tell(options_.messages, Severity::warning,
         where_from_ + ": " + std::to_string(summary_.skipped - PolygonValidityCheck::kMostListed) +
             " more skipped feature(s) not listed (" + std::to_string(summary_.skipped) + " in all)");
  }
  summary_.invalid_polygons += validity_.invalid();
  summary_.repaired_polygons += validity_.repaired();
  totals_.validity_text += validity_.summary_text();
  // Drivers report a bad filter or a broken file while reading (GeoPackage's -where, say).
  if (errors_.failed()) {
    throw ReadError(with_gdal_message(
        where_from_ + (options_.where.empty() ? ": reading failed" : ": bad -where: " + options_.where), errors_.take()));
  }
  if (const std::string pending = errors_.take(); !pending.empty()) {
    tell(options_.messages, Severity::warning, where_from_ + ": GDAL: " + pending);
  }
  // A user must never get a silently different geometry.
  const FidList& wrapped = batch_.wrapped();
  summary_.wrapped_features += wrapped.count();
  if (wrapped.count() > 0) {
    tell(options_.messages, Severity::warning,
         where_from_ + ": " + std::to_string(wrapped.count()) +
             " feature(s) have edges more than 180 degrees of longitude long joined the short way "
             "across +-180 (-wrap auto; -wrap none reads them as written) (FIDs " + wrapped.text() + ")");
  }

  if (summary_.sites == sites_before_) {
    // A table of coordinates read without open options has no geometry at all: say how to read it.
    const bool no_geometry_field = layer_->GetLayerDefn()->GetGeomFieldCount() == 0;
    throw ReadError(where_from_ + ": no usable site (" + std::to_string(summary_.features - features_before_) +
                    " features read, " + std::to_string(summary_.skipped - skipped_before_) + " skipped)" +
                    (no_geometry_field && summary_.features > 0
                         ? "; the layer has no geometry column: for a CSV of coordinates, name them with "
                           "-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat"
                         : ""));
  }
}

}  // namespace

ReadTotals::ReadTotals(SiteSet& out, const ReadOptions& options, int threads, bool time_jobs)
    : out(out), builders(options, threads) {
  out.geometry.level = options.level;
  times.time_jobs = time_jobs;
}

void read_layer(const OgrSource& source, std::size_t layer_number, const ReadOptions& options,
                gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84, ReadTotals& totals) {
  OGRLayer* const layer = source.layers[layer_number].layer;
  std::string where_from = "'" + source.name + "', layer '" + source.layers[layer_number].name + "'";
  warn_missing_dbf(source, where_from, options);
  if (!options.where.empty()) {
    errors.take();
    if (layer->SetAttributeFilter(options.where.c_str()) != OGRERR_NONE) {
      throw ReadError(with_gdal_message(where_from + ": bad -where: " + options.where, errors.take()));
    }
  }
  LayerReader reader(source, layer_number, std::move(where_from), options, errors, wgs84, totals);
  reader.read();
}

}  // namespace qtmv::sites
