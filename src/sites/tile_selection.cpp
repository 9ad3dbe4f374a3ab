#include "sites/tile_selection.hpp"

#include <ogr_geometry.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <thread>
#include <utility>

#include "common/config_option.hpp"
#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "sites/feature_examination.hpp"
#include "sites/lonlat_transform.hpp"
#include "sites/read_times.hpp"
#include "sites/split_read.hpp"
#include "sites/tile_region.hpp"

namespace qtmv::sites {

namespace {

/// Points on each side of a box transformed to a layer's CRS: its image's envelope, with a margin
/// far above the bulge of the image between them.
constexpr int kBoxSidePoints = 64;
constexpr double kProjectedMargin = 0.05;  // of the envelope's width and height, each side
/// A geographic CRS on another datum than WGS84's: shifts of at most about 1 km, and this more.
constexpr double kDatumMarginDegrees = 0.1;
/// Sources with fewer features are read whole (unless QTMV_TILE_SITES=NEAR): selecting them
/// costs more than it saves (241 country centres: 0.1 s against 0.05 s).
constexpr double kFewFeatures = 10000;
/// Most vertices of a feature that the check uses (any of its points will do).
constexpr std::size_t kMostPointsPerFeature = 256;
/// Spread over connections, a round's envelopes are cut into about this many pieces a connection
/// (a tile's surroundings are mostly one box: 98% of its sites in one read of 18, 1M points)...
constexpr double kPiecesPerReader = 4;
/// ...and an envelope into at most this many.
constexpr double kMostPieces = 64;

/// One layer of the source as the selection reads it: the CRS its coordinates are read in and the
/// transformations between it and WGS84 lon/lat (none when it is that), and what it gave so far.
struct LayerFilter {
  OGRLayer* layer = nullptr;
  std::string name;
  OGRSpatialReference srs;
  OwnedTransform to_layer, to_wgs84;
  bool geographic = true;
  double units_per_degree = 1;
  int lon_axis = 0;       // which of x, y is the longitude (geographic)
  bool shifted = false;   // longitudes beyond +-180: boxes also 360 degrees on either side
  CoordinateRange range;  // the reader's check of the coordinates
  /// The features read, by FID (a feature given by two reads is here twice until the end).
  std::vector<std::pair<GIntBig, OGRFeatureUniquePtr>> features;
  std::vector<double> x, y;  // a feature's vertices (kept from feature to feature)
  std::vector<int> ok;
};

bool is_points(OGRwkbGeometryType type) {
  const OGRwkbGeometryType flat = wkbFlatten(type);
  return flat == wkbPoint || flat == wkbMultiPoint;
}

/// Sets up `f` for `layer` (its CRS as the reader takes it); returns why it cannot be selected
/// from, or "".
std::string prepare(LayerFilter& f, const ReadOptions& options, gdal::ErrorCapture& errors,
                    const OGRSpatialReference& wgs84) {
  OGRLayer& layer = *f.layer;
  if (!layer.TestCapability(OLCFastSpatialFilter)) return "its driver has no spatial index";
  if (layer.GetLayerDefn()->GetGeomFieldCount() == 0) return "it has no geometry field";
  if (!options.source_srs.empty()) {
    if (f.srs.SetFromUserInput(options.source_srs.c_str()) != OGRERR_NONE) return "-s_srs";
    f.srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  } else if (const OGRSpatialReference* srs = layer.GetSpatialRef()) {
    f.srs = *srs;
  } else {
    f.srs = wgs84;
  }
  f.geographic = f.srs.IsGeographic();
  f.range = coordinate_range(f.srs);
  const bool points = is_points(layer.GetGeomType());
  // Lines and polygons: their envelopes hold what the reader makes of them only where their
  // edges are straight in lon/lat and none is joined across +-180.
  if (!points && !f.geographic) return "lines or polygons in a projected CRS";
  if (!points && options.edges != EdgeShape::lonlat) return "lines or polygons with -edges geodesic";
  const bool identity = f.srs.IsSame(&wgs84) && f.srs.GetDataAxisToSRSAxisMapping() == wgs84.GetDataAxisToSRSAxisMapping();
  if (!identity) {
    f.to_layer.reset(OGRCreateCoordinateTransformation(&wgs84, &f.srs));
    f.to_wgs84.reset(OGRCreateCoordinateTransformation(&f.srs, &wgs84));
    if (!f.to_layer || !f.to_wgs84) return "no transformation between its CRS and WGS84";
  }
  if (f.geographic) {
    f.units_per_degree = (M_PI / 180.0) / f.srs.GetAngularUnits(nullptr);
    double x = 10, y = 0;
    if (f.to_layer && !f.to_layer->Transform(1, &x, &y)) return "no transformation between its CRS and WGS84";
    f.lon_axis = std::fabs(x) >= std::fabs(y) ? 0 : 1;
    OGREnvelope extent;
    const bool known = layer.GetExtent(&extent, TRUE) == OGRERR_NONE;
    const double lon_min = f.lon_axis == 0 ? extent.MinX : extent.MinY, lon_max = f.lon_axis == 0 ? extent.MaxX : extent.MaxY;
    const double limit = 180.0 * f.units_per_degree;
    f.shifted = !known || lon_min < -limit || lon_max > limit;
    if (!points && options.wrap == WrapMode::automatic &&
        (!known || (extent.MaxX - extent.MinX) > limit || (extent.MaxY - extent.MinY) > limit)) {
      return "lines or polygons wider than 180 degrees with -wrap auto (edges may be joined across +-180)";
    }
  }
  errors.take();
  return "";
}

/// The envelopes in `f`'s CRS that hold `box`; false when its transformation fails there.
bool layer_envelopes(const LayerFilter& f, const LonLatBox& box, std::vector<OGREnvelope>& out) {
  OGREnvelope env;
  if (!f.to_layer) {
    env.MinX = box.lon0, env.MaxX = box.lon1, env.MinY = box.lat0, env.MaxY = box.lat1;
  } else {
    std::vector<double> x, y;
    for (int k = 0; k <= kBoxSidePoints; ++k) {
      const double t = static_cast<double>(k) / kBoxSidePoints;
      const double lon = box.lon0 + (box.lon1 - box.lon0) * t, lat = box.lat0 + (box.lat1 - box.lat0) * t;
      for (const auto& [px, py] : {std::pair{lon, box.lat0}, {lon, box.lat1}, {box.lon0, lat}, {box.lon1, lat}}) {
        x.push_back(px);
        y.push_back(py);
      }
    }
    std::vector<double> lx = x, ly = y;
    std::vector<int> ok(x.size());
    if (!f.to_layer->Transform(lx.size(), lx.data(), ly.data(), nullptr, ok.data())) return false;
    std::vector<double> bx = lx, by = ly;
    if (!f.to_wgs84->Transform(bx.size(), bx.data(), by.data(), nullptr, ok.data())) return false;
    for (std::size_t k = 0; k < x.size(); ++k) {
      // The way back must come back: a box outside the CRS's area would give no true envelope.
      const double dlon = std::fabs(std::remainder(bx[k] - x[k], 360.0));
      if (!std::isfinite(lx[k]) || !std::isfinite(ly[k]) || std::fabs(by[k] - y[k]) > 1e-6 ||
          (std::fabs(y[k]) < 89.999 && dlon > 1e-6)) {
        return false;
      }
      env.Merge(lx[k], ly[k]);
    }
    const double mx = f.geographic ? kDatumMarginDegrees * f.units_per_degree : kProjectedMargin * (env.MaxX - env.MinX);
    const double my = f.geographic ? kDatumMarginDegrees * f.units_per_degree : kProjectedMargin * (env.MaxY - env.MinY);
    env.MinX -= mx, env.MaxX += mx, env.MinY -= my, env.MaxY += my;
  }
  out.push_back(env);
  if (f.geographic && f.shifted) {
    for (const double shift : {-360.0, 360.0}) {
      OGREnvelope copy = env;
      const double d = shift * f.units_per_degree;
      if (f.lon_axis == 0) copy.MinX += d, copy.MaxX += d;
      else copy.MinY += d, copy.MaxY += d;
      out.push_back(copy);
    }
  }
  return true;
}

/// Appends up to kMostPointsPerFeature vertices of `g` to x, y; false for a geometry the reader
/// may not read as it is (a curve, -makevalid's repair), whose points then count for nothing.
bool vertices(const OGRGeometry& g, bool polygons, std::vector<double>& x, std::vector<double>& y) {
  const OGRwkbGeometryType type = wkbFlatten(g.getGeometryType());
  if (type == wkbPoint) {
    const auto& p = *g.toPoint();
    x.push_back(p.getX());
    y.push_back(p.getY());
    return true;
  }
  if (type == wkbLineString) {
    const auto& line = *g.toLineString();
    const int n = line.getNumPoints();
    if (n < 2) return false;  // not a line the reader is sure to make a site of
    const int stride = std::max<int>(1, n / static_cast<int>(kMostPointsPerFeature));
    for (int k = 0; k < n; k += stride) x.push_back(line.getX(k)), y.push_back(line.getY(k));
    return true;
  }
  if (type == wkbPolygon) {
    const OGRLinearRing* ring = g.toPolygon()->getExteriorRing();
    return polygons && ring && vertices(*ring, polygons, x, y);
  }
  if (type == wkbMultiPoint || type == wkbMultiLineString || type == wkbMultiPolygon || type == wkbGeometryCollection) {
    for (const OGRGeometry* part : *g.toGeometryCollection()) {
      if (!part || !vertices(*part, polygons, x, y)) return false;
    }
    return true;
  }
  return false;
}

/// Adds the points of `feature` in lon/lat to `points`: all or none (a feature the reader would
/// skip for a bad coordinate or a failed transformation is no site).
void add_points(LayerFilter& f, const OGRFeature& feature, bool polygons, std::vector<grid::LonLat>& points) {
  const OGRGeometry* g = feature.GetGeometryRef();
  if (!g) return;
  if (!f.to_wgs84 && wkbFlatten(g->getGeometryType()) == wkbPoint) {  // most sources: no copies
    const OGRPoint& p = *g->toPoint();
    const double lon = p.getX(), lat = p.getY();
    if (!p.IsEmpty() && std::fabs(lon) <= f.range.limit_x && std::fabs(lat) <= 90.0) points.push_back({lon, lat});
    return;
  }
  std::vector<double>&x = f.x, &y = f.y;
  x.clear();
  y.clear();
  if (g->IsEmpty() || !vertices(*g, polygons, x, y) || x.empty()) return;
  for (std::size_t k = 0; k < x.size(); ++k) {
    if (!(std::fabs(x[k]) <= f.range.limit_x && std::fabs(y[k]) <= f.range.limit_y)) return;
  }
  f.ok.assign(x.size(), 1);
  if (f.to_wgs84 && !f.to_wgs84->Transform(x.size(), x.data(), y.data(), nullptr, f.ok.data())) return;
  for (std::size_t k = 0; k < x.size(); ++k) {
    if (!f.ok[k] || !(std::fabs(x[k]) <= 540.0) || !(std::fabs(y[k]) <= 90.0)) return;
  }
  for (std::size_t k = 0; k < x.size(); ++k) points.push_back({x[k], y[k]});
}

/// Reads the features of `f` in `env`; false for one without a FID, or when GDAL reports a
/// failure (the whole read then meets it, and says so as a whole run does).
bool read_envelope(LayerFilter& f, const OGREnvelope& env, bool polygons, std::vector<grid::LonLat>& points,
                   std::uint64_t& returned, gdal::ErrorCapture& errors) {
  f.layer->SetSpatialFilterRect(env.MinX, env.MinY, env.MaxX, env.MaxY);
  f.layer->ResetReading();
  while (OGRFeatureUniquePtr feature{f.layer->GetNextFeature()}) {
    ++returned;
    const GIntBig fid = feature->GetFID();
    if (fid == OGRNullFID) return false;
    add_points(f, *feature, polygons, points);
    f.features.emplace_back(fid, std::move(feature));
  }
  return !errors.failed();
}

/// One filtered read of a round: an envelope of a layer (its index in the selection's layers).
struct EnvelopeRead {
  std::size_t layer;
  OGREnvelope envelope;
};

/// The round's envelopes of point layers cut across their longer side into pieces of about an
/// equal share of the round's area, kPiecesPerReader for each of `readers`: the same features in
/// all (a point in a closed rectangle is in one of its pieces; one on a cut, read twice, is kept
/// once), in reads of about even size. Lines and polygons are not cut: one across a cut would be
/// read once a piece, and the reads' count decides when the whole source is cheaper.
std::vector<EnvelopeRead> cut_for_readers(const std::vector<EnvelopeRead>& reads, const std::vector<LayerFilter>& layers,
                                          std::size_t readers) {
  const auto area = [](const OGREnvelope& e) { return (e.MaxX - e.MinX) * (e.MaxY - e.MinY); };
  double total = 0;
  for (const EnvelopeRead& r : reads) total += area(r.envelope);
  const double share = total / (kPiecesPerReader * static_cast<double>(readers));
  std::vector<EnvelopeRead> out;
  for (const EnvelopeRead& r : reads) {
    const OGREnvelope& e = r.envelope;
    const bool points = is_points(layers[r.layer].layer->GetGeomType());
    const double pieces = points && share > 0 ? std::clamp(std::ceil(area(e) / share), 1.0, kMostPieces) : 1.0;
    const bool across_x = e.MaxX - e.MinX >= e.MaxY - e.MinY;
    const double from = across_x ? e.MinX : e.MinY, to = across_x ? e.MaxX : e.MaxY;
    for (double k = 0; k < pieces; ++k) {
      OGREnvelope piece = e;
      const double lo = k == 0 ? from : from + (to - from) * (k / pieces);
      const double hi = k + 1 == pieces ? to : from + (to - from) * ((k + 1) / pieces);
      (across_x ? piece.MinX : piece.MinY) = lo;
      (across_x ? piece.MaxX : piece.MaxY) = hi;
      out.push_back({r.layer, piece});
    }
  }
  return out;
}

/// Why `read` failed (read_envelope's false), for the read trace.
std::string read_failure(const LayerFilter& f, const gdal::ErrorCapture& errors) {
  return "layer '" + f.name + "': " + (errors.failed() ? "GDAL failed reading it" : "features without FIDs");
}

/// A GeoPackage opened again on connections of its own for a selection's rounds (as its split
/// read is), each with the selection's layers (the same definition and -where; a copy of the
/// transformation to WGS84): the rounds' filtered reads (SQLite's R-tree queries and the
/// features' decoding, one thread a connection) go on all of them at once.
class SpreadReaders {
 public:
  /// Up to `count` connections, opened and checked on this thread; none (size() 0) where the
  /// source is not a plain GeoPackage file or a connection cannot be made as the source's.
  SpreadReaders(const OgrSource& source, const ReadOptions& options, const std::vector<LayerFilter>& layers,
                std::size_t count) {
    if (count < 2 || !EQUAL(source.dataset->GetDriverName(), "GPKG") || !source.plain_file()) return;
    const gdal::ErrorCapture quiet;  // a connection that cannot be made is none: the reads go on one
    const char* const gpkg_only[] = {"GPKG", nullptr};
    connections_.resize(count);
    for (Connection& c : connections_) {
      c.dataset = open_vector(source.name, options.open_options, gpkg_only);
      c.layers.resize(layers.size());
      for (std::size_t k = 0; c.dataset && k < layers.size(); ++k) {
        OGRLayer* layer = c.dataset->GetLayerByName(layers[k].layer->GetName());
        LayerFilter& f = c.layers[k];
        f.name = layers[k].name;
        f.range = layers[k].range;
        if (layers[k].to_wgs84) f.to_wgs84.reset(layers[k].to_wgs84->Clone());
        if (!layer || !layer->GetLayerDefn()->IsSame(layers[k].layer->GetLayerDefn()) ||
            (layers[k].to_wgs84 && !f.to_wgs84) ||
            (!options.where.empty() && layer->SetAttributeFilter(options.where.c_str()) != OGRERR_NONE)) {
          c.dataset.reset();
        }
        f.layer = layer;
      }
      if (!c.dataset || quiet.failed()) {
        connections_.clear();
        return;
      }
    }
  }
  std::size_t size() const { return connections_.size(); }

  /// Reads `reads` on every connection at once, each taking the next read; the features go to
  /// `layers`' lists, their points to `points` (their order is not a sequential read's: the
  /// caller sorts the features by FID, and the checks do not depend on it). Returns why a read
  /// failed (read_envelope's false), or "".
  std::string read(const std::vector<EnvelopeRead>& reads, bool polygons, std::vector<LayerFilter>& layers,
                   std::vector<grid::LonLat>& points, std::uint64_t& returned) {
    struct Haul {
      std::vector<grid::LonLat> points;
      std::uint64_t returned = 0;
      std::string failure;
    };
    std::vector<Haul> hauls(connections_.size());
    std::atomic<std::size_t> next{0};
    FirstException thrown;
    const auto work = [&](std::size_t c) {
      thrown.run([&] {
        gdal::ErrorCapture errors;
        Haul& haul = hauls[c];
        for (std::size_t at; haul.failure.empty() && !thrown.failed() && (at = next.fetch_add(1)) < reads.size();) {
          LayerFilter& f = connections_[c].layers[reads[at].layer];
          if (!read_envelope(f, reads[at].envelope, polygons, haul.points, haul.returned, errors)) {
            haul.failure = read_failure(f, errors);
          }
        }
      });
    };
    {
      std::vector<std::thread> threads;
      thrown.run([&] {
        for (std::size_t c = 1; c < connections_.size(); ++c) threads.emplace_back(work, c);
      });
      work(0);
      for (std::thread& t : threads) t.join();
    }
    thrown.rethrow();
    std::string failure;
    for (std::size_t c = 0; c < connections_.size(); ++c) {
      if (failure.empty()) failure = hauls[c].failure;
      points.insert(points.end(), hauls[c].points.begin(), hauls[c].points.end());
      returned += hauls[c].returned;
      for (std::size_t k = 0; k < layers.size(); ++k) {
        auto& from = connections_[c].layers[k].features;
        layers[k].features.insert(layers[k].features.end(), std::make_move_iterator(from.begin()),
                                  std::make_move_iterator(from.end()));
        from.clear();
      }
    }
    return failure;
  }

 private:
  struct Connection {
    GDALDatasetUniquePtr dataset;
    std::vector<LayerFilter> layers;
  };
  std::vector<Connection> connections_;
};

/// The features of `f` by FID, each once.
std::vector<OGRFeatureUniquePtr> by_fid(LayerFilter& f) {
  std::sort(f.features.begin(), f.features.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<OGRFeatureUniquePtr> out;
  out.reserve(f.features.size());
  for (std::size_t k = 0; k < f.features.size(); ++k) {
    if (k == 0 || f.features[k].first != f.features[k - 1].first) out.push_back(std::move(f.features[k].second));
  }
  f.features.clear();
  return out;
}

}  // namespace

TileSelection select_tile_features(const OgrSource& source, const ReadOptions& options, gdal::ErrorCapture& errors,
                                   const OGRSpatialReference& wgs84) {
  const auto start = std::chrono::steady_clock::now();
  TileSelection out;
  std::vector<LayerFilter> layers(source.layers.size());
  const auto read_all = [&](const std::string& why) {
    for (LayerFilter& f : layers) {
      if (f.layer) f.layer->SetSpatialFilter(nullptr);
    }
    errors.take();
    out.used = false;
    out.why = why;
    out.features.clear();
    return std::move(out);
  };
  const char* mode = config_option("QTMV_TILE_SITES");
  if (mode && EQUAL(mode, "ALL")) return read_all("QTMV_TILE_SITES=ALL");
  const bool always = mode && EQUAL(mode, "NEAR");
  if (!options.sql.empty()) return read_all("-sql");

  double total = 0;  // features of the layers
  for (std::size_t k = 0; k < layers.size(); ++k) {
    LayerFilter& f = layers[k];
    f.layer = source.layers[k].layer;
    f.name = source.layers[k].name;
    if (!options.where.empty() && f.layer->SetAttributeFilter(options.where.c_str()) != OGRERR_NONE) {
      return read_all("-where");  // the read says what is wrong with it
    }
    if (const std::string why = prepare(f, options, errors, wgs84); !why.empty()) return read_all("layer '" + f.name + "': " + why);
    // The merge checks it against the features it reads (a site added since is not listed).
    const GIntBig count = f.layer->GetFeatureCount(TRUE);
    if (count < 0) return read_all("layer '" + f.name + "': its features cannot be counted");
    total += static_cast<double>(count);
  }
  // A few sites are read whole faster than their surroundings are worked out.
  if (!always && total < kFewFeatures) return read_all("few features (QTMV_TILE_SITES=NEAR selects them still)");
  const int level = options.level;
  const int coarse = coarse_level(level, total);
  double boxes_s = 0, read_s = 0, verify_s = 0;
  auto t_caps = std::chrono::steady_clock::now();
  std::vector<RegionCap> caps = tile_caps(options.tile_range, level, coarse, 0.5 * site_spacing(total));
  const double caps_s = seconds_since(t_caps);
  ReadRegion region(ReadRegion::step_for(caps));
  std::vector<grid::LonLat> points;
  std::uint64_t returned = 0, reads = 0;
  int rounds = 0;
  // A GeoPackage's reads spread over connections of their own, as its split read is.
  SpreadReaders spread(source, options, layers, std::min(kMostReaders, static_cast<std::size_t>(thread_count(options.threads))));
  std::size_t most_readers = 1;
  for (std::size_t left = caps.size(); left > 0; ++rounds) {
    report_progress(options.progress, 0.0, "selecting sites");
    auto t0 = std::chrono::steady_clock::now();
    const std::vector<LonLatBox> boxes = region.next_boxes(caps);
    boxes_s += seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    for (const RegionCap& cap : caps) {
      // A cap that reaches round the sphere: the whole source is cheaper read once.
      if (!cap.verified && cap.radius + cap.reach >= M_PI) {
        return read_all("a cap of the tile reaches round the sphere (too few sites near it)");
      }
    }
    std::vector<EnvelopeRead> round;
    for (std::size_t k = 0; k < layers.size(); ++k) {
      for (const LonLatBox& box : boxes) {
        std::vector<OGREnvelope> envelopes;
        if (!layer_envelopes(layers[k], box, envelopes)) {
          return read_all("layer '" + layers[k].name + "': its CRS does not hold the tile's surroundings");
        }
        for (const OGREnvelope& env : envelopes) round.push_back({k, env});
      }
    }
    reads += round.size();
    std::string failure;
    if (spread.size() > 1) {
      failure = spread.read(cut_for_readers(round, layers, spread.size()), !options.make_valid, layers, points, returned);
      most_readers = spread.size();
    } else {
      for (const EnvelopeRead& r : round) {
        if (!read_envelope(layers[r.layer], r.envelope, !options.make_valid, points, returned, errors)) {
          failure = read_failure(layers[r.layer], errors);
          break;
        }
      }
    }
    if (!failure.empty()) return read_all(failure);
    // Reading most of the source again and again costs more than reading it once.
    if (static_cast<double>(returned) > 2.0 * total + 1000.0) return read_all("the tile's surroundings hold most sites");
    read_s += seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    left = verify_caps(caps, PointIndex(points, total));
    verify_s += seconds_since(t0);
  }
  std::size_t kept = 0;
  for (LayerFilter& f : layers) {
    f.layer->SetSpatialFilter(nullptr);
    out.features.push_back(by_fid(f));
    kept += out.features.back().size();
  }
  errors.take();
  out.used = true;
  out.source_features = static_cast<std::uint64_t>(total);
  char text[256];
  std::snprintf(text, sizeof text,
                "%zu of %.0f features (%llu given by %llu filtered reads in %d rounds on %zu connection%s; %zu caps of "
                "level %d), %.3f s (caps %.3f, boxes %.3f, reads %.3f, checks %.3f)",
                kept, total, static_cast<unsigned long long>(returned), static_cast<unsigned long long>(reads), rounds,
                most_readers, most_readers == 1 ? "" : "s", caps.size(), coarse, seconds_since(start), caps_s, boxes_s, read_s, verify_s);
  out.why = text;
  return out;
}

}  // namespace qtmv::sites
