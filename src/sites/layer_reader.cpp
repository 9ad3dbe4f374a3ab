#include "sites/layer_reader.hpp"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "sites/append_sites.hpp"
#include "sites/feature_count.hpp"
#include "sites/feature_examination.hpp"
#include "sites/feature_parts.hpp"
#include "sites/lonlat_transform.hpp"
#include "sites/polygon_validity.hpp"
#include "sites/read_step.hpp"
#include "sites/split_read.hpp"

namespace qtmv::sites {

namespace {

/// A layer's CRS, the transformation from it to WGS84 (none when it is WGS84 in lon/lat order),
/// and the range its coordinates are checked against.
struct LayerCrs {
  OGRSpatialReference source;
  OwnedTransform transform;
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
std::uint64_t& skip_counter(ReadSummary& summary, Skip why) {
  switch (why) {
    case Skip::unreadable: return summary.skipped_unreadable;
    case Skip::type: return summary.skipped_type;
    case Skip::coordinate: return summary.skipped_coordinate;
    case Skip::transform: return summary.skipped_transform;
    default: return summary.skipped_empty;
  }
}

/// Adds `seconds` to `total` (from any thread of a step).
void add_time(double& total, double seconds) {
#pragma omp atomic
  total += seconds;
}

/// One layer's reading, its filter set: the per-layer state, from its CRS to its last batch.
class LayerReader {
 public:
  LayerReader(const OgrSource& source, std::size_t layer_number, std::string where_from, const ReadOptions& options,
              gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84, ReadTotals& totals,
              std::vector<OGRFeatureUniquePtr>* selected);
  /// Reads the features, builds their sites, then says what the layer's reading found.
  void read();

 private:
  /// A chunk of features on its way: read, examined, settled, built, appended.
  struct Slot {
    FeatureChunk chunk;
    SiteBatch batch;
    SiteAppend append;
  };
  /// A chunk is read while the one before is examined, the one before that settled, and so on:
  /// a slot for each.
  static constexpr std::size_t kSlots = 5;

  bool step(std::size_t r, std::size_t& chunks);
  void read_chunk(FeatureChunk& chunk);
  void settle_chunk(Slot& slot);
  void settle(FeatureChunk& chunk, std::size_t k, SiteBatch& batch);
  bool to_lonlat(GIntBig fid, grid::LonLat* points, std::size_t count);
  void skip(GIntBig fid, const std::string& reason, std::uint64_t& counter);
  void finish();
  /// The next feature: the layer's, or the selection's; null at the end.
  OGRFeatureUniquePtr next_feature();
  /// The features to read; -1 while not known.
  GIntBig feature_count() {
    return selected_ ? static_cast<GIntBig>(selected_->size()) : feature_count_.get();
  }

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
  // The layer's features read by several GDAL datasets at once, in its order; null: by the layer.
  const std::unique_ptr<SplitRead> split_;
  FeatureCount feature_count_;  // not counted for a split read (its progress is its lines')
  std::vector<OGRFeatureUniquePtr>* const selected_;  // null: the layer's features
  std::size_t next_selected_ = 0;
  ThreadTransforms transforms_;
  // GDAL reads the features on this thread, which reports them and makes them jobs in feature
  // order; their parts, coordinate checks, transformation and polygon validity are found, and
  // their sites built and appended, on all threads: the same messages and sites whatever the
  // thread count.
  std::array<Slot, kSlots> slots_;
  bool read_all_ = false;
  bool reserved_ = false;  // the site table's room for the layer's features, once they are counted
  LonLatScratch scratch_;
  FidList wrapped_;
  GIntBig wrapped_fid_ = -1;  // the last feature named in `wrapped_`
};

LayerReader::LayerReader(const OgrSource& source, std::size_t layer_number, std::string where_from,
                         const ReadOptions& options, gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84,
                         ReadTotals& totals, std::vector<OGRFeatureUniquePtr>* selected)
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
      split_(selected ? nullptr : SplitRead::open(source, layer_number, options, totals.builders.threads(), where_from_)),
      feature_count_(split_ ? FeatureCount() : FeatureCount(source, layer_number, options, totals.builders.threads())),
      selected_(selected),
      transforms_(crs_.transform.get(), totals.builders.threads()) {}

void LayerReader::read() {
  errors_.take();
  if (!selected_ && !split_) layer_->ResetReading();
  std::size_t chunks = 0;  // chunks read so far
  for (std::size_t r = 0; step(r, chunks); ++r) {
  }
  finish();
}

// Step r reads chunk r on this thread and settles chunk r - 2, while the team examines chunk
// r - 1, builds chunk r - 3 and appends chunk r - 4; after the step this thread names the
// features -wrap auto changed and plans the next append (the arrays sized), in feature order.
bool LayerReader::step(std::size_t r, std::size_t& chunks) {
  const auto at = [&](std::size_t back) { return r >= back && r - back < chunks ? &slots_[(r - back) % kSlots] : nullptr; };
  Slot* const reading = read_all_ ? nullptr : &slots_[r % kSlots];
  Slot *const examined = at(1), *const settled = at(2), *const built = at(3), *const appended = at(4);
  if (!reading && !examined && !settled && !built && !appended) return false;
  const std::size_t builds = built ? built->batch.slice_count() : 0;
  const std::size_t examines = examined ? examined->chunk.block_count() : 0;
  const std::size_t copies = appended ? appended->append.unit_count() : 0;
  // A split read's features were made on other threads: their memory goes back on all threads.
  const std::size_t releases = appended && split_ ? appended->chunk.block_count() : 0;
  std::size_t features = 0, vertices = 0;
  for (const Slot* slot : {examined, built, appended}) {
    if (slot) features += slot->chunk.size(), vertices += slot->chunk.vertex_count();
  }
  const int threads = totals_.builders.threads();
  ReadTimes& times = totals_.times;
  const Examination examination{crs_.range, validity_, transforms_};
  auto share_end = std::chrono::steady_clock::now();
  run_step(
      team_for_work(threads, features, vertices), builds + examines + copies + releases,
      [&] {
        const auto start = share_end;
        if (reading) read_chunk(reading->chunk);
        const auto read_end = std::chrono::steady_clock::now();
        if (settled) settle_chunk(*settled);
        share_end = std::chrono::steady_clock::now();
        times.read_s += std::chrono::duration<double>(read_end - start).count();
        times.settled_s += std::chrono::duration<double>(share_end - read_end).count();
      },
      [&](std::size_t u) {
        const auto start = std::chrono::steady_clock::now();
        if (u < builds) {
          built->batch.build_slice(u, totals_.builders, times);
          add_time(times.built_s, seconds_since(start));
        } else if (u < builds + examines) {
          examined->chunk.examine_block(u - builds, examination);
          add_time(times.examined_s, seconds_since(start));
        } else if (u < builds + examines + copies) {
          appended->append.copy(u - builds - examines);
          add_time(times.appended_s, seconds_since(start));
        } else {
          appended->chunk.release_block(u - builds - examines - copies);
          add_time(times.appended_s, seconds_since(start));
        }
      });
  if (reading && reading->chunk.size() > 0) ++chunks;
  const auto step_end = std::chrono::steady_clock::now();
  if (built) {
    built->batch.name_wrapped(wrapped_, wrapped_fid_);
    built->append.plan(totals_.out.geometry, built->batch, threads);
  }
  if (appended) {
    appended->batch.clear();
    appended->chunk.clear();
  }
  times.appended_s += seconds_since(step_end);
  times.rasterise += std::chrono::steady_clock::now() - share_end;  // what the reading did not hide
  return true;
}

/// Reads the next chunk of features (this thread: GDAL's messages are caught here).
void LayerReader::read_chunk(FeatureChunk& chunk) {
  if (!reserved_) {
    if (const GIntBig count = feature_count(); count > 0) {
      totals_.out.table.sites.reserve(totals_.out.table.sites.size() + static_cast<std::size_t>(count));
      reserved_ = true;
    }
  }
  while (!chunk.full()) {
    OGRFeatureUniquePtr feature = next_feature();
    if (!feature) {
      read_all_ = true;
      return;
    }
    ++summary_.features;
    if (options_.progress && summary_.features % 256 == 0) {
      // The layer's start while its count is not known (yet): a stop is still asked for.
      const GIntBig count = feature_count();
      const double done = split_      ? split_->fraction_done()
                          : count > 0 ? std::min(1.0, static_cast<double>(summary_.features - features_before_) / count)
                                      : 0.0;
      if (!options_.progress((static_cast<double>(layer_number_) + done) / static_cast<double>(layer_count_),
                             "reading sites")) {
        throw Interrupted();
      }
    }
    chunk.add(std::move(feature), errors_);
  }
}

OGRFeatureUniquePtr LayerReader::next_feature() {
  if (split_) return split_->next();
  if (!selected_) return OGRFeatureUniquePtr(layer_->GetNextFeature());
  if (next_selected_ == selected_->size()) return nullptr;
  return std::move((*selected_)[next_selected_++]);
}

void LayerReader::settle_chunk(Slot& slot) {
  const std::size_t n = slot.chunk.size();
  for (std::size_t k = 0; k < n; ++k) {
    // GDAL made the features long before (a chunk ago): their memory is fetched ahead of the
    // geometry's release, which waited on it (a third of the settling of a million points).
    if (k + 8 < n) {
      __builtin_prefetch(slot.chunk.feature(k + 8).geometry.get());
      __builtin_prefetch(slot.chunk.feature(k + 8).feature.get());
    }
    settle(slot.chunk, k, slot.batch);
  }
  slot.batch.plan_slices();
}

/// Reports an examined feature, or makes it a site whose jobs wait in the batch.
void LayerReader::settle(FeatureChunk& chunk, std::size_t k, SiteBatch& batch) {
  PendingFeature& pending = chunk.feature(k);
  const GIntBig fid = pending.fid;
  const auto release = [&pending, this] {  // its geometry's memory back before the next
    if (split_) return;  // made on another thread: given back by the team (release_block)
    pending.geometry.reset();
    pending.feature.reset();
  };
  if (pending.skip != Skip::none) {
    skip(fid, pending.skip_reason, skip_counter(summary_, pending.skip));
    release();
    return;
  }
  FeatureParts* parts = &chunk.block_parts(pending.block);
  std::size_t part_begin = pending.part_begin, part_end = pending.part_end;
  // Invalid polygons are named (or repaired, -makevalid) as the source gives them.
  if (validity_.settle(fid, pending.geometry, pending.problem)) {
    parts = &chunk.own_parts();
    std::string reason;
    if (!gather_parts(*pending.geometry, *parts, reason) || parts->parts.empty()) {
      skip(fid, "nothing left after -makevalid", summary_.skipped_empty);
      release();
      return;
    }
    part_begin = 0;
    part_end = parts->parts.size();
    if (!to_lonlat(fid, parts->points.data(), parts->points.size())) {
      release();
      return;
    }
  } else if (pending.late_skip == Skip::transform) {
    // Transformed again here, in feature order: the transformation's messages count the failures.
    const std::size_t first = parts->parts[part_begin].begin, last = parts->parts[part_end - 1].end;
    if (!to_lonlat(fid, parts->points.data() + first, last - first)) {
      release();
      return;
    }
  } else if (pending.late_skip != Skip::none) {
    skip(fid, pending.late_reason, skip_counter(summary_, pending.late_skip));
    release();
    return;
  }

  // --- one site, built with its batch ---
  SiteRecord record;
  record.fid = fid;
  record.layer = layer_index_;
  for (std::size_t p = part_begin; p < part_end; ++p) {
    const FeatureParts::Kind kind = parts->parts[p].kind;
    record.kind |= kind == FeatureParts::kPoint ? kPointSite : kind == FeatureParts::kLine ? kLineSite : kPolygonSite;
  }
  record.attributes.reset(pending.feature.release());
  SiteTable& table = totals_.out.table;
  const auto site = static_cast<std::int32_t>(table.sites.size());
  table.sites.push_back(std::move(record));
  ++summary_.sites;
  batch.add(fid, site, *parts, part_begin, part_end);
  release();
}

/// Transforms `count` points to WGS84 with the layer's transformation, on this thread;
/// false when the feature is skipped.
bool LayerReader::to_lonlat(GIntBig fid, grid::LonLat* points, std::size_t count) {
  gdal::ErrorCapture transform_errors;
  std::string reason;
  const Skip why = sites::to_lonlat(points, count, crs_.transform.get(), transform_errors, scratch_, reason);
  if (why == Skip::none) return true;
  skip(fid, reason, skip_counter(summary_, why));
  return false;
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
  const FidList& wrapped = wrapped_;
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
                gdal::ErrorCapture& errors, const OGRSpatialReference& wgs84, ReadTotals& totals,
                std::vector<OGRFeatureUniquePtr>* selected) {
  OGRLayer* const layer = source.layers[layer_number].layer;
  std::string where_from = "'" + source.name + "', layer '" + source.layers[layer_number].name + "'";
  warn_missing_dbf(source, where_from, options);
  if (!options.where.empty()) {
    errors.take();
    if (layer->SetAttributeFilter(options.where.c_str()) != OGRERR_NONE) {
      throw ReadError(with_gdal_message(where_from + ": bad -where: " + options.where, errors.take()));
    }
  }
  LayerReader reader(source, layer_number, std::move(where_from), options, errors, wgs84, totals, selected);
  reader.read();
}

}  // namespace qtmv::sites
