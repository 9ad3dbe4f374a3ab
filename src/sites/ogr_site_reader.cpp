#include "sites/ogr_site_reader.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "gdal/error_capture.hpp"
#include "grid/qtm_checks.hpp"
#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "sites/fid_list.hpp"
#include "sites/polygon_validity.hpp"
#include "sites/site_builder.hpp"
#include "sites/site_cells.hpp"

namespace qtmv::sites {

EdgeShape parse_edge_shape(const std::string& text) {
  if (text == "lonlat") return EdgeShape::lonlat;
  if (text == "geodesic") return EdgeShape::geodesic;
  throw ReadError("-edges: '" + text + "' is not one of lonlat, geodesic");
}

WrapMode parse_wrap_mode(const std::string& text) {
  if (text == "auto") return WrapMode::automatic;
  if (text == "none") return WrapMode::none;
  throw ReadError("-wrap: '" + text + "' is not one of auto, none");
}

DistanceRule parse_distance_rule(const std::string& text) {
  if (text == "exact") return DistanceRule::exact;
  if (text == "cell") return DistanceRule::cell;
  throw ReadError("-distance: '" + text + "' is not one of exact, cell");
}

namespace {

std::string with_gdal_message(std::string text, const std::string& gdal) {
  if (!gdal.empty()) text += " (GDAL: " + gdal + ")";
  return text;
}

struct OgrDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};

/// A feature's geometry as coordinate runs in the source CRS, before any transformation.
struct FeatureParts {
  enum Kind { kPoint, kLine, kRing };
  struct Part {
    Kind kind;
    std::size_t begin, end;  // range in x, y
    int polygon;             // rings: index of their polygon
  };
  std::vector<double> x, y;
  std::vector<Part> parts;
  int polygons = 0;

  void add_curve(const OGRSimpleCurve& curve, Kind kind, int polygon) {
    const int n = curve.getNumPoints();
    if (n == 0) return;
    const std::size_t begin = x.size();
    for (int k = 0; k < n; ++k) {
      x.push_back(curve.getX(k));
      y.push_back(curve.getY(k));
    }
    parts.push_back({kind, begin, x.size(), polygon});
  }
};

/// Gathers the parts of a (linear) geometry; false with `reason` for an unsupported type.
bool gather_parts(const OGRGeometry& geometry, FeatureParts& out, std::string& reason) {
  if (geometry.IsEmpty()) return true;
  switch (wkbFlatten(geometry.getGeometryType())) {
    case wkbPoint: {
      const auto& p = *geometry.toPoint();
      out.x.push_back(p.getX());
      out.y.push_back(p.getY());
      out.parts.push_back({FeatureParts::kPoint, out.x.size() - 1, out.x.size(), -1});
      return true;
    }
    case wkbLineString:
      out.add_curve(*geometry.toLineString(), FeatureParts::kLine, -1);
      return true;
    case wkbPolygon:
    case wkbTriangle: {
      const auto& polygon = *geometry.toPolygon();
      const int index = out.polygons++;
      if (const OGRLinearRing* ring = polygon.getExteriorRing()) out.add_curve(*ring, FeatureParts::kRing, index);
      for (int k = 0; k < polygon.getNumInteriorRings(); ++k) {
        out.add_curve(*polygon.getInteriorRing(k), FeatureParts::kRing, index);
      }
      return true;
    }
    case wkbMultiPoint:
    case wkbMultiLineString:
    case wkbMultiPolygon:
    case wkbGeometryCollection: {
      const auto& collection = *geometry.toGeometryCollection();
      for (int k = 0; k < collection.getNumGeometries(); ++k) {
        if (!gather_parts(*collection.getGeometryRef(k), out, reason)) return false;
      }
      return true;
    }
    default:
      reason = std::string("unsupported geometry type ") + OGRGeometryTypeToName(geometry.getGeometryType());
      return false;
  }
}

/// Bounds (in the source CRS's units) beyond which coordinates are not handed to PROJ.
struct CoordinateRange {
  double limit_x = 0, limit_y = 0;
  std::string describe;  // for messages
};

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

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

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
/// Features read before they are examined on all threads: work for every thread, memory bounded.
constexpr std::size_t kChunkFeatures = 1024;
constexpr std::size_t kChunkVertices = std::size_t{1} << 20;

/// The points of a geometry's curves (a bound on its vertices, for the chunks' size).
std::size_t point_count(const OGRGeometry& geometry) {
  switch (wkbFlatten(geometry.getGeometryType())) {
    case wkbPolygon:
    case wkbTriangle: {
      const auto& polygon = *geometry.toPolygon();
      std::size_t n = 0;
      for (const OGRLinearRing* ring : polygon) n += static_cast<std::size_t>(ring->getNumPoints());
      return n;
    }
    case wkbLineString:
      return static_cast<std::size_t>(geometry.toLineString()->getNumPoints());
    case wkbMultiPoint:
    case wkbMultiLineString:
    case wkbMultiPolygon:
    case wkbGeometryCollection: {
      std::size_t n = 0;
      for (const OGRGeometry* part : *geometry.toGeometryCollection()) n += point_count(*part);
      return n;
    }
    default:
      return 1;
  }
}

/// A pending feature's parts, coordinate checks and polygon validity, or why it is skipped.
/// Changes only `pending`: several threads examine a chunk's features at once.
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

/// The summary's count of the features skipped for `why`.
std::uint64_t& skip_counter(ReadSummary& summary, PendingFeature::Skip why) {
  switch (why) {
    case PendingFeature::Skip::unreadable: return summary.skipped_unreadable;
    case PendingFeature::Skip::type: return summary.skipped_type;
    case PendingFeature::Skip::coordinate: return summary.skipped_coordinate;
    default: return summary.skipped_empty;
  }
}

/// A feature's site, or a share of its parts, to be traced and filled: its coordinates (lon/lat,
/// shared by the shares) and parts.
struct SiteJob {
  GIntBig fid = 0;
  bool starts_site = true;  ///< the first share of its feature (the others add to its site)
  std::shared_ptr<const std::vector<grid::LonLat>> lonlat;
  std::vector<FeatureParts::Part> parts;
};
/// Jobs and coordinates per batch: enough work for every thread, memory bounded.
constexpr std::size_t kBatchSites = 4096;
constexpr std::size_t kBatchVertices = std::size_t{1} << 22;
/// A feature with more vertices than this is shared out by its parts (whole polygons), so that
/// one large multipolygon (a continent's coasts) keeps several threads busy.
constexpr std::size_t kShareVertices = std::size_t{1} << 12;

/// The feature's parts as jobs: one, or shares of about kShareVertices vertices, split between
/// polygons (a polygon's rings stay together). The split depends on the feature only.
void make_jobs(GIntBig fid, std::vector<grid::LonLat>&& lonlat, std::vector<FeatureParts::Part>&& parts,
               std::vector<SiteJob>& out) {
  auto shared = std::make_shared<const std::vector<grid::LonLat>>(std::move(lonlat));
  SiteJob job{fid, true, shared, {}};
  std::size_t vertices = 0;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const bool polygon_starts = parts[p].kind != FeatureParts::kRing || p == 0 ||
                                parts[p - 1].kind != FeatureParts::kRing || parts[p - 1].polygon != parts[p].polygon;
    if (polygon_starts && vertices >= kShareVertices) {
      out.push_back(std::move(job));
      job = SiteJob{fid, false, shared, {}};
      vertices = 0;
    }
    job.parts.push_back(parts[p]);
    vertices += parts[p].end - parts[p].begin;
  }
  out.push_back(std::move(job));
}

/// Traces and fills one site with `builder` (a polygon's rings together).
void build_site(SiteBuilder& builder, const SiteJob& job) {
  builder.begin_site();
  for (std::size_t p = 0; p < job.parts.size();) {
    const FeatureParts::Part& part = job.parts[p];
    if (part.kind == FeatureParts::kPoint) {
      builder.add_point((*job.lonlat)[part.begin]);
      ++p;
    } else if (part.kind == FeatureParts::kLine) {
      builder.add_line(job.lonlat->data() + part.begin, part.end - part.begin);
      ++p;
    } else {
      std::vector<LonLatPath> rings;
      const int polygon = part.polygon;
      for (; p < job.parts.size() && job.parts[p].kind == FeatureParts::kRing && job.parts[p].polygon == polygon; ++p) {
        rings.emplace_back(job.lonlat->begin() + job.parts[p].begin, job.lonlat->begin() + job.parts[p].end);
      }
      builder.add_polygon(rings);
    }
  }
  builder.end_site();
}

/// Calls copy(k, first, last) for the positions [first, last) of part k of an array whose parts
/// start at `starts` (ascending; starts[n] its end), on all threads in slices of equal size: one
/// large part (a continent's coasts) keeps every thread busy, not one.
template <class Copy>
void copy_parts_in_slices(const std::vector<std::size_t>& starts, int threads, const Copy& copy) {
  constexpr std::size_t kSlice = std::size_t{1} << 16;
  const std::size_t begin = starts.front(), end = starts.back();
  const auto slices = static_cast<std::int64_t>((end - begin + kSlice - 1) / kSlice);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t slice = 0; slice < slices; ++slice) {
    const std::size_t first = begin + static_cast<std::size_t>(slice) * kSlice;
    const std::size_t last = std::min(end, first + kSlice);
    auto k = static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), first) - starts.begin()) - 1;
    for (; k + 1 < starts.size() && starts[k] < last; ++k) {
      const std::size_t from = std::max(first, starts[k]), to = std::min(last, starts[k + 1]);
      if (from < to) copy(k, from, to);
    }
  }
}

/// Appends a batch's built sites to `out`, `built[k]` (its site id 0) as site `ids[k]`
/// (ascending), its piece indices moved past the pieces before it: the arrays of appending them
/// one by one, each grown once and copied on all threads.
void append_sites(SiteGeometry& out, const std::vector<SiteGeometry>& built, const std::vector<std::int32_t>& ids,
                  int threads) {
  const std::size_t n = built.size();
  if (n == 0) return;
  std::vector<std::size_t> pieces(n + 1), cells(n + 1), fixed(n + 1), nodes(n + 1);
  pieces[0] = out.pieces.size();
  cells[0] = out.site_cells.size();
  fixed[0] = out.fixed_cells.size();
  nodes[0] = out.fixed_nodes.size();
  for (std::size_t k = 0; k < n; ++k) {
    pieces[k + 1] = pieces[k] + built[k].pieces.size();
    cells[k + 1] = cells[k] + built[k].site_cells.size();
    fixed[k + 1] = fixed[k] + built[k].fixed_cells.size();
    nodes[k + 1] = nodes[k] + built[k].fixed_nodes.size();
  }
  out.pieces.resize(pieces[n]);
  out.site_cells.resize(cells[n]);
  out.fixed_cells.resize(fixed[n]);
  out.fixed_nodes.resize(nodes[n]);
  copy_parts_in_slices(pieces, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const SitePiece* in = built[k].pieces.data();
    for (std::size_t i = from; i < to; ++i) {
      out.pieces[i] = in[i - pieces[k]];
      out.pieces[i].site = ids[k];
    }
  });
  copy_parts_in_slices(cells, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const SiteCell* in = built[k].site_cells.data();
    const auto piece_offset = static_cast<std::uint32_t>(pieces[k]);
    for (std::size_t i = from; i < to; ++i) {
      SiteCell c = in[i - cells[k]];
      c.site = ids[k];
      c.piece_begin += piece_offset;
      c.piece_end += piece_offset;
      out.site_cells[i] = c;
    }
  });
  copy_parts_in_slices(fixed, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const FixedCell* in = built[k].fixed_cells.data();
    for (std::size_t i = from; i < to; ++i) out.fixed_cells[i] = {in[i - fixed[k]].code, ids[k]};
  });
  copy_parts_in_slices(nodes, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const FixedNode* in = built[k].fixed_nodes.data();
    for (std::size_t i = from; i < to; ++i) {
      const FixedNode& node = in[i - nodes[k]];
      out.fixed_nodes[i] = {node.code, node.level, ids[k]};
    }
  });
  out.site_count = ids[n - 1] + 1;
}


}  // namespace

SiteSet read_sites(const std::string& dataset_name, const ReadOptions& options) {
  const auto read_start = std::chrono::steady_clock::now();
  grid::require_level(options.level);
  GDALAllRegister();
  auto say = [&](Severity severity, const std::string& message) {
    if (options.messages) options.messages(severity, message);
  };

  // --- the dataset and the layer ----------------------------------------------------------------
  // A FIFO, socket or device would block GDAL's open for ever (a FIFO without a writer) or be
  // read past its end: only files and directories are opened by name.
  struct stat local;
  if (dataset_name.rfind("/vsi", 0) != 0 && stat(dataset_name.c_str(), &local) == 0 && !S_ISREG(local.st_mode) &&
      !S_ISDIR(local.st_mode)) {
    throw ReadError("cannot open '" + dataset_name + "': not a regular file or directory (" +
                    (S_ISFIFO(local.st_mode) ? "a FIFO" : S_ISSOCK(local.st_mode) ? "a socket" : "a device") +
                    "); for standard input use /vsistdin/");
  }
  gdal::ErrorCapture errors;
  CPLStringList open_options;
  for (const std::string& option : options.open_options) open_options.AddString(option.c_str());
  GDALDatasetUniquePtr dataset(GDALDataset::Open(dataset_name.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr,
                                                 open_options.List()));
  if (!dataset) {
    VSIStatBufL stat;
    if (VSIStatL(dataset_name.c_str(), &stat) != 0) {
      // In /vsizip/ and the like, a file that is not an archive of that kind looks missing too.
      const bool virtual_path = dataset_name.rfind("/vsi", 0) == 0;
      throw ReadError(with_gdal_message(
          "cannot open '" + dataset_name + "': no such file" + (virtual_path ? ", or not a readable archive" : ""),
          errors.take()));
    }
    throw ReadError(with_gdal_message("cannot open '" + dataset_name + "' as a vector dataset", errors.take()));
  }
  // The open's warnings (an -oo the driver does not know, say) would be dropped below: pass them on.
  if (const std::string warnings = errors.take(); !warnings.empty()) {
    say(Severity::warning, "'" + dataset_name + "': GDAL: " + warnings);
  }
  // --- the layers: the -sql result, the -l layers (several: composite sites), or the first ----
  struct SourceLayer {
    OGRLayer* layer;
    std::string name;
  };
  std::vector<SourceLayer> layers;
  std::shared_ptr<OGRLayer> sql_result;  // released through the dataset
  if (!options.sql.empty()) {
    errors.take();
    OGRLayer* layer = dataset->ExecuteSQL(options.sql.c_str(), nullptr, options.dialect.empty() ? nullptr : options.dialect.c_str());
    if (!layer) {
      throw ReadError(with_gdal_message("'" + dataset_name + "': -sql failed: " + options.sql, errors.take()));
    }
    sql_result.reset(layer, [ds = dataset.get()](OGRLayer* l) { ds->ReleaseResultSet(l); });
    layers.push_back({layer, "(-sql result)"});
  } else if (!options.layers.empty()) {
    for (const std::string& name : options.layers) {
      OGRLayer* layer = dataset->GetLayerByName(name.c_str());
      if (!layer) {
        std::string names;
        for (int k = 0; k < dataset->GetLayerCount(); ++k) names += std::string(k ? ", " : "") + dataset->GetLayer(k)->GetName();
        throw ReadError("'" + dataset_name + "' has no layer '" + name + "'; its layers: " + (names.empty() ? "(none)" : names));
      }
      layers.push_back({layer, layer->GetName()});
    }
  } else {
    if (dataset->GetLayerCount() == 0) throw ReadError("'" + dataset_name + "' has no layer");
    layers.push_back({dataset->GetLayer(0), dataset->GetLayer(0)->GetName()});
  }
  std::string where_all = "'" + dataset_name + "', layer" + (layers.size() > 1 ? "s " : " ");
  for (std::size_t k = 0; k < layers.size(); ++k) where_all += (k ? ", '" : "'") + layers[k].name + "'";

  SiteSet out;
  ReadSummary& summary = out.summary;
  SiteGeometry& geometry = out.geometry;
  geometry.level = options.level;
  std::chrono::steady_clock::duration rasterise{};  // tracing, filling and claims, within the read
  // QTMV_READ_TRACE set: the parts' times on stderr (for tuning).
  const bool trace = std::getenv("QTMV_READ_TRACE") != nullptr;
  double examined_s = 0, built_s = 0, longest_job_s = 0, appended_s = 0;
  const ScopedDefaultThreads thread_limit(options.threads);  // the claims' sorts too
  const int threads = thread_count(options.threads);
  std::vector<std::unique_ptr<SiteBuilder>> builders(static_cast<std::size_t>(threads));
  std::string validity_text;  // the layers' invalid polygons, for the summary line
  // Each layer's sites follow the layer before's (composite sites), each with its own CRS,
  // checks and messages.
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  report_progress(options.progress, 0.0, "reading sites");
  for (std::size_t layer_number = 0; layer_number < layers.size(); ++layer_number) {
    OGRLayer* const layer = layers[layer_number].layer;
    const std::string& layer_name = layers[layer_number].name;
    const std::uint64_t features_before = summary.features, sites_before = summary.sites,
                        skipped_before = summary.skipped;
    const std::string where_from = "'" + dataset_name + "', layer '" + layer_name + "'";
    // GDAL opens a shapefile without its .dbf silently, with no fields: say the attributes are gone.
    if (EQUAL(dataset->GetDriverName(), "ESRI Shapefile") && EQUAL(CPLGetExtension(dataset_name.c_str()), "shp")) {
      VSIStatBufL dbf;
      if (VSIStatL(CPLResetExtension(dataset_name.c_str(), "dbf"), &dbf) != 0 &&
          VSIStatL(CPLResetExtension(dataset_name.c_str(), "DBF"), &dbf) != 0) {
        say(Severity::warning, where_from + ": no .dbf beside the .shp; the sites have no attributes");
      }
    }
    if (!options.where.empty()) {
      errors.take();
      if (layer->SetAttributeFilter(options.where.c_str()) != OGRERR_NONE) {
        throw ReadError(with_gdal_message(where_from + ": bad -where: " + options.where, errors.take()));
      }
    }

    // --- CRS ------------------------------------------------------------------------------------------
    OGRSpatialReference source;
    if (!options.source_srs.empty()) {
      errors.take();
      if (source.SetFromUserInput(options.source_srs.c_str()) != OGRERR_NONE) {
        throw ReadError(with_gdal_message("-s_srs: cannot read '" + options.source_srs + "'", errors.take()));
      }
      source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    } else if (const OGRSpatialReference* layer_srs = layer->GetSpatialRef()) {
      source = *layer_srs;  // keeps the layer's data axis order
    } else {
      say(Severity::warning, where_from + ": the layer has no CRS; its coordinates are taken as EPSG:4326 (WGS84 lon/lat)");
      source = wgs84;
    }
    std::unique_ptr<OGRCoordinateTransformation, OgrDeleter> transform;
    if (!(source.IsSame(&wgs84) && source.GetDataAxisToSRSAxisMapping() == wgs84.GetDataAxisToSRSAxisMapping())) {
      errors.take();
      transform.reset(OGRCreateCoordinateTransformation(&source, &wgs84));
      if (!transform) {
        throw ReadError(with_gdal_message(where_from + ": no transformation from its CRS (" +
                                              std::string(source.GetName() ? source.GetName() : "?") + ") to WGS84",
                                          errors.take()));
      }
    }
    const CoordinateRange range = coordinate_range(source);

    // --- features --------------------------------------------------------------------------------------
    const std::uint32_t layer_index = out.table.add_source(layer->GetLayerDefn(), dataset_name, layer_name);
    PolygonValidityCheck validity(options, source, where_from);
    const GIntBig feature_count = layer->GetFeatureCount(FALSE);

    // One warning a skipped feature, the first kMostListed of them; then a count (a CSV read without
    // its coordinate columns would otherwise give a line per row).
    auto skip = [&](GIntBig fid, const std::string& reason, std::uint64_t& counter) {
      const std::string message = where_from + ", FID " + std::to_string(fid) + ": " + reason;
      if (options.strict) throw ReadError(message + " (-strict)");
      if (summary.skipped < PolygonValidityCheck::kMostListed) say(Severity::warning, message + "; feature skipped");
      ++summary.skipped;
      ++counter;
    };

    std::vector<grid::LonLat> lonlat;
    std::vector<int> transformed_ok;
    FidList wrapped;  // the features -wrap auto changed

    // Sites are traced and filled in batches on all threads, each job (a feature, or a share of a
    // large one's parts) by one thread's builder, and appended in feature order: the same geometry
    // whatever the thread count.
    std::vector<SiteJob> batch;
    std::size_t batch_vertices = 0;
    GIntBig wrapped_fid = -1;  // the last feature named in `wrapped`
    auto build_batch = [&] {
      if (batch.empty()) return;
      const auto start = std::chrono::steady_clock::now();
      const auto n = static_cast<std::int64_t>(batch.size());
      std::vector<SiteGeometry> built(batch.size());
      std::vector<std::size_t> short_way(batch.size(), 0);
      FirstException failure;
  #pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
      for (std::int64_t k = 0; k < n; ++k) {
        failure.run([&] {
          std::unique_ptr<SiteBuilder>& builder = builders[static_cast<std::size_t>(thread_index())];
          if (!builder) builder = std::make_unique<SiteBuilder>(options.level, options.edges, options.wrap);
          const double job_start = trace ? seconds_since(start) : 0.0;
          build_site(*builder, batch[static_cast<std::size_t>(k)]);
          if (trace) {
            const double job = seconds_since(start) - job_start;
#pragma omp critical(qtmv_read_trace)
            longest_job_s = std::max(longest_job_s, job);
          }
          short_way[k] = builder->short_way_edges();
          built[k] = builder->take_geometry();
        });
      }
      failure.rethrow();
      // A feature's shares come one after another: its first starts the site, the others add to it.
      // Appended batch by batch: holding every batch's built sites until the end of the read made
      // the runs of 135 000 points peak 500 MB higher (measured at level 13), for no gain in time.
      std::vector<std::int32_t> ids(batch.size());
      std::int32_t next_id = geometry.site_count;
      for (std::size_t k = 0; k < batch.size(); ++k) ids[k] = batch[k].starts_site ? next_id++ : next_id - 1;
      const double append_start = seconds_since(start);
      append_sites(geometry, built, ids, threads);
      built_s += append_start;
      appended_s += seconds_since(start) - append_start;
      for (std::size_t k = 0; k < batch.size(); ++k) {
        const bool named = !batch[k].starts_site && wrapped_fid == batch[k].fid;
        if (short_way[k] > 0 && !named) {
          wrapped.add(batch[k].fid);
          wrapped_fid = batch[k].fid;
        }
      }
      batch.clear();
      batch_vertices = 0;
      rasterise += std::chrono::steady_clock::now() - start;
    };
    // Features are read in chunks: GDAL reads them on this thread; their parts, coordinate checks
    // and polygon validity are found on all threads; then, in feature order, they are reported and
    // become sites: the same messages and sites whatever the thread count.
    std::vector<PendingFeature> chunk;
    std::size_t chunk_vertices = 0;
    auto settle_chunk = [&] {
      const auto n = static_cast<std::int64_t>(chunk.size());
      const auto examine_start = std::chrono::steady_clock::now();
      FirstException failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
      for (std::int64_t k = 0; k < n; ++k) {
        failure.run([&] { examine(chunk[static_cast<std::size_t>(k)], range, validity); });
      }
      failure.rethrow();
      examined_s += seconds_since(examine_start);
      for (PendingFeature& pending : chunk) {
        const GIntBig fid = pending.fid;
        if (pending.skip != PendingFeature::Skip::none) {
          skip(fid, pending.skip_reason, skip_counter(summary, pending.skip));
          continue;
        }
        FeatureParts& parts = pending.parts;
        std::unique_ptr<OGRGeometry>& geometry = pending.geometry;
        // Invalid polygons are named (or repaired, -makevalid) as the source gives them.
        if (validity.settle(fid, geometry, pending.problem)) {
          parts = FeatureParts{};
          std::string reason;
          if (!gather_parts(*geometry, parts, reason) || parts.parts.empty()) {
            skip(fid, "nothing left after -makevalid", summary.skipped_empty);
            continue;
          }
        }
        const std::size_t n_points = parts.x.size();
        bool usable = true;
        if (transform) {
          transformed_ok.assign(n_points, FALSE);
          gdal::ErrorCapture transform_errors;
          const std::vector<double> x0 = parts.x, y0 = parts.y;
          transform->Transform(static_cast<int>(n_points), parts.x.data(), parts.y.data(), nullptr,
                               transformed_ok.data());
          for (std::size_t k = 0; k < n_points && usable; ++k) {
            if (!transformed_ok[k] || !std::isfinite(parts.x[k]) || !std::isfinite(parts.y[k])) {
              skip(fid, with_gdal_message("coordinate " + format_coordinate(x0[k], y0[k]) + " fails to transform to WGS84",
                                          transform_errors.take()),
                   summary.skipped_transform);
              usable = false;
            }
          }
          if (!usable) continue;
        }
        lonlat.resize(n_points);
        for (std::size_t k = 0; k < n_points && usable; ++k) {
          double lat = parts.y[k];
          if (std::fabs(lat) > 90.0) {
            if (std::fabs(lat) > 90.0 + 1e-9) {
              skip(fid, std::string("latitude beyond +-90") + (transform ? " after transformation" : "") + " at " +
                            format_coordinate(parts.x[k], lat),
                   summary.skipped_coordinate);
              usable = false;
              break;
            }
            lat = lat > 0 ? 90.0 : -90.0;  // rounding in the transformation
          }
          lonlat[k] = {parts.x[k], lat};
        }
        if (!usable) continue;

        // --- one site, built with the next batch ---
        SiteRecord record;
        record.fid = fid;
        record.layer = layer_index;
        for (const FeatureParts::Part& part : parts.parts) {
          record.kind |= part.kind == FeatureParts::kPoint ? kPointSite : part.kind == FeatureParts::kLine ? kLineSite
                                                                                                           : kPolygonSite;
        }
        record.attributes.reset(pending.feature.release());
        out.table.sites.push_back(std::move(record));
        ++summary.sites;
        batch_vertices += lonlat.size();
        make_jobs(fid, std::move(lonlat), std::move(parts.parts), batch);
        lonlat = {};
        pending = PendingFeature{};  // its geometry's memory back before the next
        if (batch.size() >= kBatchSites || batch_vertices >= kBatchVertices) build_batch();
      }
      chunk.clear();
      chunk_vertices = 0;
    };
    errors.take();
    layer->ResetReading();
    for (OGRFeatureUniquePtr feature(layer->GetNextFeature()); feature; feature.reset(layer->GetNextFeature())) {
      ++summary.features;
      if (options.progress && feature_count > 0 && summary.features % 256 == 0 &&
          !options.progress((static_cast<double>(layer_number) +
                             std::min(1.0, static_cast<double>(summary.features - features_before) / feature_count)) /
                                static_cast<double>(layers.size()),
                            "reading sites")) {
        throw Interrupted();
      }
      PendingFeature& pending = chunk.emplace_back();
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
      if (pending.geometry) chunk_vertices += point_count(*pending.geometry);
      if (chunk.size() >= kChunkFeatures || chunk_vertices >= kChunkVertices) settle_chunk();
    }
    settle_chunk();
    build_batch();
    validity.finish();
    if (summary.skipped > PolygonValidityCheck::kMostListed) {
      say(Severity::warning, where_from + ": " + std::to_string(summary.skipped - PolygonValidityCheck::kMostListed) +
                                 " more skipped feature(s) not listed (" + std::to_string(summary.skipped) + " in all)");
    }
    summary.invalid_polygons += validity.invalid();
    summary.repaired_polygons += validity.repaired();
    validity_text += validity.summary_text();
    // Drivers report a bad filter or a broken file while reading (GeoPackage's -where, say).
    if (errors.failed()) {
      throw ReadError(with_gdal_message(
          where_from + (options.where.empty() ? ": reading failed" : ": bad -where: " + options.where), errors.take()));
    }
    if (const std::string pending = errors.take(); !pending.empty()) say(Severity::warning, where_from + ": GDAL: " + pending);
    // A user must never get a silently different geometry.
    summary.wrapped_features += wrapped.count();
    if (wrapped.count() > 0) {
      say(Severity::warning, where_from + ": " + std::to_string(wrapped.count()) +
                                 " feature(s) have edges more than 180 degrees of longitude long joined the short way "
                                 "across +-180 (-wrap auto; -wrap none reads them as written) (FIDs " + wrapped.text() +
                                 ")");
    }

    if (summary.sites == sites_before) {
      // A table of coordinates read without open options has no geometry at all: say how to read it.
      const bool no_geometry_field = layer->GetLayerDefn()->GetGeomFieldCount() == 0;
      throw ReadError(where_from + ": no usable site (" + std::to_string(summary.features - features_before) +
                      " features read, " + std::to_string(summary.skipped - skipped_before) + " skipped)" +
                      (no_geometry_field && summary.features > 0
                           ? "; the layer has no geometry column: for a CSV of coordinates, name them with "
                             "-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat"
                           : ""));
    }
  }

  report_progress(options.progress, 1.0, "reading sites");

  // --- claims, counts, summary --------------------------------------------------------------------
  for (const auto& builder : builders) summary.vertex_steps += builder ? builder->vertex_steps() : 0;
  const auto claims_start = std::chrono::steady_clock::now();
  const SiteCellCounts counts = resolve_claims(out.geometry, options.distance);
  rasterise += std::chrono::steady_clock::now() - claims_start;
  if (trace) {
    std::fprintf(stderr,
                 "read trace: %d threads: features examined %.3f s; sites built %.3f s (longest job %.3f s), "
                 "appended %.3f s; claims %.3f s; whole read %.3f s\n",
                 threads, examined_s, built_s, longest_job_s, appended_s, seconds_since(claims_start),
                 seconds_since(read_start));
  }
  summary.rasterise_seconds = std::chrono::duration<double>(rasterise).count();
  FidList without_cell;
  for (std::size_t s = 0; s < out.table.sites.size(); ++s) {
    SiteRecord& r = out.table.sites[s];
    r.site_cells = counts.site_cells[s];
    r.fixed_cells = counts.fixed_cells[s];
    r.has_own_cell = counts.has_own_cell[s];
    if (!r.has_own_cell) without_cell.add(r.fid);
  }
  summary.sites_without_own_cell = without_cell.count();
  if (without_cell.count() > 0 && options.warn_sites_without_cell) {
    say(Severity::warning, where_all + ": " + std::to_string(without_cell.count()) +
                               " site(s) have no cell of their own at level " + std::to_string(options.level) +
                               " (FIDs " + without_cell.text() + "); they are still written");
  }
  std::string line = where_all + ": " + std::to_string(summary.features) + " features, " +
                     std::to_string(summary.sites) + " sites, " + std::to_string(out.geometry.pieces.size()) +
                     " pieces, " + std::to_string(out.geometry.site_cells.size()) + " site cells, " +
                     std::to_string(out.geometry.fixed_cells.size()) + " fixed cells and " +
                     std::to_string(out.geometry.fixed_nodes.size()) + " fixed nodes at level " +
                     std::to_string(options.level);
  line += validity_text;
  if (summary.skipped > 0) {
    line += "; " + std::to_string(summary.skipped) + " features skipped (" + std::to_string(summary.skipped_empty) +
            " empty, " + std::to_string(summary.skipped_type) + " unsupported type, " +
            std::to_string(summary.skipped_coordinate) + " bad coordinate, " +
            std::to_string(summary.skipped_transform) + " failed transformation, " +
            std::to_string(summary.skipped_unreadable) + " unreadable)";
  }
  say(summary.skipped > 0 ? Severity::warning : Severity::info, line);
  return out;
}

}  // namespace qtmv::sites
