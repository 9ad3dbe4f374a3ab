#include "write/vector_writer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <future>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include "common/default_init_allocator.hpp"
#include "common/radix_sort.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm.hpp"
#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "write/gpkg_rows.hpp"
#include "write/region_measures.hpp"
#include "write/region_tracer.hpp"

namespace qtmv::write {

const char* const kVectorLayerNames[4] = {"regions", "boundary_cells", "voronoi_edges", "cells"};

namespace {

using grid::Cell;
using grid::Code;

constexpr std::uint64_t kTransactionFeatures = 100000;  // features per transaction
constexpr std::uint64_t kProgressEvery = 1024;          // features between progress calls
constexpr std::size_t kEdgePairBlock = 4096;            // voronoi_edges pairs measured at once
constexpr std::size_t kRegionBlock = 2048;              // regions traced at once

// --- GDAL errors -----------------------------------------------------------------------------

struct DatasetCloser {
  void operator()(GDALDataset* dataset) const { GDALClose(dataset); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

struct FeatureDeleter {
  void operator()(OGRFeature* feature) const { OGRFeature::DestroyFeature(feature); }
};
using FeaturePtr = std::unique_ptr<OGRFeature, FeatureDeleter>;

// --- tracing ---------------------------------------------------------------------------------

/// QTMV_WRITE_TRACE set: each step's wall time on stderr (for tuning), as QTMV_LABEL_TRACE does
/// for the labeller.
class StepTrace {
 public:
  void operator()(const char* step) {
    if (!on_) return;
    const auto now = std::chrono::steady_clock::now();
    std::fprintf(stderr, "trace: write %-28s %9.3f ms\n", step, std::chrono::duration<double, std::milli>(now - last_).count());
    last_ = now;
  }
  /// Starts the next step's clock here (what ran since is not traced).
  void restart() { last_ = std::chrono::steady_clock::now(); }
  /// A figure of the step just traced (seconds).
  void note(const char* what, double seconds) const {
    if (on_) std::fprintf(stderr, "trace: write   %-26s %9.3f ms\n", what, seconds * 1e3);
  }

 private:
  bool on_ = std::getenv("QTMV_WRITE_TRACE") != nullptr;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// --- working ahead of writing -----------------------------------------------------------------

/// Runs work(first, last), which returns the results of items first .. last - 1 (regions traced,
/// pairs' lines linked and measured: in parallel with OpenMP), on a helper thread one block ahead
/// of write(first, last, results) on this thread: OGR writes one feature at a time, so working on
/// the next block overlaps writing this one, and no more than two blocks are held. An exception
/// from either side comes out of here (after the helper has finished its block).
template <class Work, class Write>
void work_ahead(std::size_t count, std::size_t block, const Work& work, const Write& write) {
  using Results = decltype(work(std::size_t{0}, std::size_t{0}));
  const auto ahead = [&](std::size_t first) {
    return std::async(std::launch::async, [&work, first, last = std::min(count, first + block)] {
      return work(first, last);
    });
  };
  std::future<Results> next;
  if (count > 0) next = ahead(0);
  for (std::size_t first = 0; first < count; first += block) {
    const Results results = next.get();
    if (first + block < count) next = ahead(first + block);
    write(first, std::min(count, first + block), results);
  }
}

// --- voronoi edges ---------------------------------------------------------------------------

/// One cell edge between two sites: key = site a << 32 | site b (a < b), edge = the cell of
/// site a << 2 | the edge's index in its drawn ring.
struct EdgeRef {
  std::uint64_t key, edge;
  bool operator<(const EdgeRef& o) const { return key < o.key || (key == o.key && edge < o.edge); }
};

/// Every edge between cells of different sites, once (from the cell of the lower site id: the
/// two drawings of an edge on +-180, at +180 and -180, are one edge), sorted by pair. Such an
/// edge has a boundary cell on each side: the outline cells hold them all.
DefaultInitVector<EdgeRef> gather_edges(const label::Outlines& outlines) {
  const int level = outlines.level;
  const label::OutlineCells& cells = outlines.cells;
  const auto n = static_cast<std::int64_t>(cells.size());
  // Thread t of the team takes the t-th run of cells, so its edges come in cell order, k after
  // k: joined in thread order they are sorted by `edge`, and a stable radix sort by pair leaves
  // them sorted by (key, edge).
  std::vector<std::vector<EdgeRef>> parts(static_cast<std::size_t>(thread_count(0)));
  FirstException failure;
#pragma omp parallel num_threads(thread_count(0))
  {
    const auto team = static_cast<std::int64_t>(team_size()), t = static_cast<std::int64_t>(thread_index());
    std::vector<EdgeRef>& local = parts[static_cast<std::size_t>(t)];
    for (std::int64_t c = n * t / team; c < n * (t + 1) / team; ++c) {
      const label::OutlineCell& outline = cells[static_cast<std::size_t>(c)];
      if (!outline.boundary) continue;
      const Code code = outline.code;
      const std::int32_t site = outline.site;
      failure.run([&] {
        Code nb[3];
        grid::neighbours(code, level, nb);
        int across[grid::kMaxPolygonCorners];
        const int corners = drawn_edges(grid::cell_of(code, level), across);
        for (int k = 0; k < corners; ++k) {
          if (across[k] == kAcrossPoleLine) continue;
          const std::int32_t other = label::site_of_near(cells, static_cast<std::size_t>(c), nb[across[k]]);
          if (other > site) {
            local.push_back({static_cast<std::uint64_t>(site) << 32 | static_cast<std::uint32_t>(other),
                             code << 2 | static_cast<std::uint64_t>(k)});
          }
        }
      });
    }
  }
  failure.rethrow();
  std::vector<std::size_t> at(parts.size() + 1, 0);
  for (std::size_t t = 0; t < parts.size(); ++t) at[t + 1] = at[t] + parts[t].size();
  DefaultInitVector<EdgeRef> all(at.back());  // every slot copied below
#pragma omp parallel for schedule(static, 1) num_threads(thread_count(0))
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(parts.size()); ++t) {
    std::copy(parts[static_cast<std::size_t>(t)].begin(), parts[static_cast<std::size_t>(t)].end(),
              all.begin() + static_cast<std::ptrdiff_t>(at[static_cast<std::size_t>(t)]));
    std::vector<EdgeRef>().swap(parts[static_cast<std::size_t>(t)]);
  }
  // Pairs (a, b) as a * sites + b: one key of the fewest bits.
  const auto sites = static_cast<std::uint64_t>(std::max(1, outlines.site_count));
  radix_sort(all, bits_for(sites * sites - 1),
             [sites](const EdgeRef& e) { return (e.key >> 32) * sites + (e.key & 0xffffffffu); });
  return all;
}

struct Segment {
  LonLat from, to;
};

/// The lines of one pair and their geodesic length.
struct PairLines {
  std::vector<std::vector<LonLat>> lines;
  double length_m = 0;
};

/// Links a pair's cell edges (all with site a on their left) into lines: an edge continues the
/// one that ends where it starts. Edges that do not meet (across +-180, across a pole) start
/// new lines. The length is the sum of the edges' geodesic lengths in kLengthUnit; `measured`
/// (may be null) is that sum over the edges off the cut at +-180, from the regions' pass
/// (RegionAreaSums), and only the others are solved here: the same sum either way.
PairLines link_pair(const EdgeRef* begin, const EdgeRef* end, int level, const std::uint64_t* measured) {
  std::vector<Segment> segments;
  segments.reserve(static_cast<std::size_t>(end - begin));
  PairLines out;
  std::uint64_t units = measured ? *measured : 0;
  for (const EdgeRef* e = begin; e != end; ++e) {
    LonLat ring[grid::kMaxPolygonCorners];
    const int corners = grid::cell_polygon(grid::cell_of(e->edge >> 2, level), level, ring);
    const int k = static_cast<int>(e->edge & 3u);
    const Segment& s = segments.emplace_back(Segment{ring[k], ring[(k + 1) % corners]});
    if (!measured || on_cut(s.from, s.to)) units += length_units(geodesic_length(s.from, s.to));
  }
  out.length_m = static_cast<double>(units) * kLengthUnit;
  std::sort(segments.begin(), segments.end(), [](const Segment& a, const Segment& b) {
    return point_less(a.from, b.from) || (same_point(a.from, b.from) && point_less(a.to, b.to));
  });
  std::vector<LonLat> ends;
  ends.reserve(segments.size());
  for (const Segment& s : segments) ends.push_back(s.to);
  std::sort(ends.begin(), ends.end(), point_less);
  const auto has_incoming = [&](const LonLat& p) {
    const auto it = std::lower_bound(ends.begin(), ends.end(), p, point_less);
    return it != ends.end() && same_point(*it, p);
  };
  std::vector<char> used(segments.size(), 0);
  const auto unused_from = [&](const LonLat& p) {
    auto it = std::lower_bound(segments.begin(), segments.end(), p,
                               [](const Segment& s, const LonLat& q) { return point_less(s.from, q); });
    for (; it != segments.end() && same_point(it->from, p); ++it) {
      const auto k = static_cast<std::size_t>(it - segments.begin());
      if (!used[k]) return k;
    }
    return segments.size();
  };
  const auto follow = [&](std::size_t k) {
    std::vector<LonLat> line{segments[k].from};
    while (k < segments.size()) {
      used[k] = 1;
      line.push_back(segments[k].to);
      k = unused_from(segments[k].to);
    }
    out.lines.push_back(std::move(line));
  };
  // Open lines from their starts first, then what is left are closed loops.
  for (std::size_t k = 0; k < segments.size(); ++k) {
    if (!used[k] && !has_incoming(segments[k].from)) follow(k);
  }
  for (std::size_t k = 0; k < segments.size(); ++k) {
    if (!used[k]) follow(k);
  }
  return out;
}

/// A pair's lines linked ahead of writing, and their GeoPackage blob for direct rows (the lines
/// then dropped).
struct MeasuredPair {
  PairLines lines;
  GpkgGeometry geometry;
};

// --- OGR helpers -----------------------------------------------------------------------------

OGRLinearRing* make_ring(const LonLat* points, std::size_t n) {
  auto* ring = new OGRLinearRing;
  ring->setNumPoints(static_cast<int>(n + 1), FALSE);
  for (std::size_t k = 0; k < n; ++k) ring->setPoint(static_cast<int>(k), points[k].lon, points[k].lat);
  ring->setPoint(static_cast<int>(n), points[0].lon, points[0].lat);
  return ring;
}

OGRMultiPolygon* make_multipolygon(const Region& region) {
  auto* multi = new OGRMultiPolygon;
  for (const RegionPolygon& part : region) {
    auto* polygon = new OGRPolygon;
    polygon->addRingDirectly(make_ring(part.shell.data(), part.shell.size()));
    for (const auto& hole : part.holes) polygon->addRingDirectly(make_ring(hole.data(), hole.size()));
    multi->addGeometryDirectly(polygon);
  }
  return multi;
}

/// A region as the GeoPackage blob of its MultiPolygon (what make_multipolygon gives OGR).
void region_geometry(const Region& region, GpkgGeometry& out) {
  out.begin(GpkgGeometry::kMultiPolygon, static_cast<std::uint32_t>(region.size()));
  for (const RegionPolygon& part : region) {
    out.polygon(static_cast<std::uint32_t>(1 + part.holes.size()));
    out.ring(part.shell.data(), part.shell.size());
    for (const auto& hole : part.holes) out.ring(hole.data(), hole.size());
  }
  out.end();
}

/// Sets the feature's polygon (made by cell_feature) to the ring of `n` points, in place.
void set_ring(OGRFeature& feature, const LonLat* ring, int n) {
  OGRLinearRing* r = feature.GetGeometryRef()->toPolygon()->getExteriorRing();
  r->setNumPoints(n + 1, FALSE);
  for (int k = 0; k < n; ++k) r->setPoint(k, ring[k].lon, ring[k].lat);
  r->setPoint(n, ring[0].lon, ring[0].lat);
}

/// A feature whose geometry is an empty polygon with one ring, for set_ring.
FeaturePtr cell_feature(OGRLayer* layer) {
  FeaturePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
  auto* polygon = new OGRPolygon;
  polygon->addRingDirectly(new OGRLinearRing);
  feature->SetGeometryDirectly(polygon);
  return feature;
}

/// A site's FID as a field value: null for OGRNullFID.
RowValue fid_value(std::int64_t fid) { return fid == OGRNullFID ? RowValue{} : RowValue::of(fid); }

void set_value(OGRFeature& feature, int field, const RowValue& value) {
  switch (value.kind) {
    case RowValue::Kind::null: feature.SetFieldNull(field); break;
    case RowValue::Kind::integer: feature.SetField(field, static_cast<GIntBig>(value.integer)); break;
    case RowValue::Kind::real: feature.SetField(field, value.real); break;
    case RowValue::Kind::text: feature.SetField(field, value.text); break;
  }
}

CPLStringList string_list(const std::vector<std::string>& items) {
  CPLStringList list;
  for (const std::string& item : items) list.AddString(item.c_str());
  return list;
}

// --- the writer ------------------------------------------------------------------------------

/// The dataset being written: layers, fields, transactions, progress and errors.
class Writer {
 public:
  Writer(const std::string& path, const VectorOptions& options, gdal::ErrorCapture& trap, double total_work)
      : path_(path), options_(options), trap_(trap), total_work_(std::max(total_work, 1.0)) {
    srs_.importFromEPSG(4326);
    srs_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }

  void open(GDALDriver* driver) {
    const CPLStringList dsco = string_list(options_.dataset_options);
    dataset_.reset(driver->Create(path_.c_str(), 0, 0, 0, GDT_Unknown, dsco.List()));
    if (!dataset_) fail("cannot create the dataset");
    check("creating the dataset");
    transactions_ = dataset_->TestCapability(ODsCTransactions) != 0;
    driver_name_ = driver->GetDescription();
    const char* types = driver->GetMetadataItem(GDAL_DMD_CREATIONFIELDDATATYPES);
    if (types) field_types_ = CPLStringList(CSLTokenizeString(types));
  }

  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  /// Left without close(): a failure or an interrupt, and the file will be removed. Nothing of
  /// it needs finishing (a GeoPackage would build its deferred spatial index at close, which
  /// takes many seconds on millions of features), so drop the open transaction and ask GDAL
  /// not to flush.
  ~Writer() {
    if (!dataset_) return;
    CPLErrorStateBackuper keep_error_state;  // what happens here must not mask the error being thrown
    CPLPushErrorHandler(CPLQuietErrorHandler);
    if (transaction_open_) dataset_->RollbackTransaction();
    dataset_->MarkSuppressOnClose();
    CPLPopErrorHandler();
  }

  /// Closes the dataset; throws if GDAL reported any error meanwhile.
  void close() {
    layer_name_.clear();
    dataset_.reset();
    check("closing the dataset");
  }

  /// Creates a layer; `work` is its share of the progress (features it will write, about).
  /// `per_cell`: a layer of millions of cell polygons (boundary_cells, cells), which gets no
  /// GeoPackage spatial index unless the layer options ask for one (see the header).
  OGRLayer* begin_layer(const char* name, OGRwkbGeometryType type, double work, bool per_cell = false) {
    layer_name_ = name;
    layer_work_ = work;
    layer_done_ = 0;
    CPLStringList lco = string_list(options_.layer_options);
    if (per_cell && EQUAL(driver_name_.c_str(), "GPKG") && lco.FetchNameValue("SPATIAL_INDEX") == nullptr) {
      lco.SetNameValue("SPATIAL_INDEX", "NO");
    }
    layer_ = dataset_->CreateLayer(name, &srs_, type, lco.List());
    if (!layer_) fail("cannot create the layer");
    check("creating the layer");
    return layer_;
  }

  /// Adds a field; returns its index in the layer (drivers may launder its name). A type the
  /// driver does not list (a list in a shapefile) becomes String with a warning, as ogr2ogr does:
  /// OGRFeature::SetFieldsFrom then writes the values as text.
  int add_field(OGRFieldDefn& field) {
    const char* type = OGRFieldDefn::GetFieldTypeName(field.GetType());
    if (!field_types_.empty() && field_types_.FindString(type) < 0 && field.GetType() != OFTString) {
      CPLError(CE_Warning, CPLE_AppDefined, "%s, layer %s: the %s driver has no %s fields: field %s written as String",
               path_.c_str(), layer_name_.c_str(), driver_name_.c_str(), type, field.GetNameRef());
      field.SetType(OFTString);
      field.SetSubType(OFSTNone);
      field.SetWidth(0);
      field.SetPrecision(0);
    }
    const int before = layer_->GetLayerDefn()->GetFieldCount();
    if (layer_->CreateField(&field, TRUE) != OGRERR_NONE || layer_->GetLayerDefn()->GetFieldCount() != before + 1) {
      fail(std::string("cannot create the field ") + field.GetNameRef());
    }
    check(std::string("creating the field ") + field.GetNameRef());
    return before;
  }

  /// Starts writing features (after the fields are made).
  void begin_features() {
    if (transactions_) start_transaction();
  }

  void write(OGRFeature& feature) {
    feature.SetFID(OGRNullFID);  // CreateFeature sets it: let the driver assign the next one
    if (layer_->CreateFeature(&feature) != OGRERR_NONE) fail("cannot write a feature");
    if (trap_.failed()) check("writing a feature");
    count_row();
  }

  /// Rows straight into the current layer's GeoPackage table (see gpkg_rows.hpp); null where
  /// that does not apply.
  std::unique_ptr<GpkgRows> direct_rows(const std::vector<int>& fields) {
    std::unique_ptr<GpkgRows> rows = guard([&] { return GpkgRows::open(*dataset_, *layer_, fields); });
    check("preparing the layer's rows");
    return rows;
  }

  /// Adds a row to `rows` (direct rows of the current layer) and books it.
  void write(GpkgRows& rows, const GpkgGeometry& geometry, const RowValue* values) {
    guard([&] { rows.add(geometry, values); });
    count_row();
  }

  /// Runs `work` (direct rows), its WriteError named as our own failures are.
  template <class Work>
  auto guard(Work&& work) -> decltype(work()) {
    try {
      return work();
    } catch (const WriteError& e) {
      fail(e.what());
    }
  }

  /// Books one row written (by write() or direct rows): transactions, progress, interrupts.
  void count_row() {
    ++in_transaction_;
    if (transactions_ && in_transaction_ >= kTransactionFeatures) {
      commit();
      start_transaction();
    }
    if (++since_progress_ >= kProgressEvery) {  // the layer reports its share; this catches an interrupt
      since_progress_ = 0;
      report();
    }
  }

  /// Reports progress within the layer: `done` of `count` features.
  void layer_progress(double done, double count) {
    layer_done_ = count > 0 ? layer_work_ * std::min(1.0, done / count) : layer_work_;
    report();
  }

  void end_layer() {
    if (transactions_) commit();
    work_done_ += layer_work_;
    layer_done_ = 0;
    report();
  }

  /// The last report, once the dataset is closed (too late to interrupt).
  void report_done() {
    if (options_.progress) options_.progress(1.0, "write");
  }

  [[noreturn]] void fail(const std::string& what) const {
    std::string message = path_;
    if (!layer_name_.empty()) message += ", layer " + layer_name_;
    message += ": " + what;
    if (trap_.failed()) message += ": " + trap_.take();
    throw WriteError(message);
  }

 private:
  void check(const std::string& what) const {
    if (trap_.failed()) fail(what);
  }
  void start_transaction() {
    if (dataset_->StartTransaction(FALSE) != OGRERR_NONE) fail("cannot start a transaction");
    transaction_open_ = true;
    in_transaction_ = 0;
  }
  void commit() {
    transaction_open_ = false;
    if (dataset_->CommitTransaction() != OGRERR_NONE) fail("cannot commit a transaction");
    check("committing a transaction");
    in_transaction_ = 0;
  }
  void report() {
    if (!options_.progress) return;
    const double fraction = std::min(1.0, (work_done_ + layer_done_) / total_work_);
    if (!options_.progress(fraction, "write")) throw Interrupted();
  }

  std::string path_;
  const VectorOptions& options_;
  gdal::ErrorCapture& trap_;
  OGRSpatialReference srs_;
  DatasetPtr dataset_;
  OGRLayer* layer_ = nullptr;
  std::string layer_name_, driver_name_;
  CPLStringList field_types_;  ///< the driver's GDAL_DMD_CREATIONFIELDDATATYPES (empty: not stated)
  bool transactions_ = false, transaction_open_ = false;
  std::uint64_t in_transaction_ = 0, since_progress_ = 0;
  double total_work_, work_done_ = 0, layer_work_ = 0, layer_done_ = 0;
};

/// A name for one of our fields that no source field has (compared without case).
std::string unique_field_name(const std::string& name, const OGRFeatureDefn* source) {
  const auto taken = [&](const std::string& candidate) { return source && source->GetFieldIndex(candidate.c_str()) >= 0; };
  if (!taken(name)) return name;
  std::string candidate = "qtmv_" + name;
  for (int k = 2; taken(candidate); ++k) candidate = "qtmv_" + name + "_" + std::to_string(k);
  return candidate;
}

/// Where a per-cell layer's polygons go: straight into its GeoPackage table (GpkgRows), or
/// else through OGR, one reused feature at a time. Values come in the order of `fields`.
class CellRows {
 public:
  CellRows(Writer& w, OGRLayer* layer, std::vector<int> fields)
      : w_(w), fields_(std::move(fields)), direct_(w.direct_rows(fields_)) {
    if (!direct_) feature_ = cell_feature(layer);
  }

  void add(Code code, int level, const RowValue* values) {
    LonLat ring[grid::kMaxPolygonCorners];
    const int n = grid::cell_polygon(grid::cell_of(code, level), level, ring);
    if (direct_) {
      direct_polygon_.begin(GpkgGeometry::kPolygon, 1);
      direct_polygon_.ring(ring, static_cast<std::size_t>(n));
      direct_polygon_.end();
      w_.write(*direct_, direct_polygon_, values);
      return;
    }
    set_ring(*feature_, ring, n);
    for (std::size_t k = 0; k < fields_.size(); ++k) set_value(*feature_, fields_[k], values[k]);
    w_.write(*feature_);
  }

  /// After the last add(), before the layer ends.
  void finish() {
    if (direct_) w_.guard([&] { direct_->finish(); });
  }

 private:
  Writer& w_;
  std::vector<int> fields_;
  std::unique_ptr<GpkgRows> direct_;
  GpkgGeometry direct_polygon_;  // the cell's blob, for direct rows
  FeaturePtr feature_;
};

// --- the layers ------------------------------------------------------------------------------

struct Input {
  const label::Outlines& outlines;
  const CellTileSource& cell_tiles;  ///< the cells layer's labels
  const sites::SiteTable& table;
  std::int32_t site_count;
  bool all_ring_vertices;  ///< VectorOptions::all_ring_vertices
  int geodesic_device;     ///< VectorOptions::geodesic_device
  const MessageSink& messages;

  /// Composite sites (several source layers): every layer says which layer its sites came from.
  bool composite() const { return table.source_count() > 1; }
  /// The name of the source layer of site s, as a field value.
  RowValue layer_of(std::size_t s) const { return RowValue::of(table.layer(table.sites[s].layer)); }
};

/// Whether the sources' values can go into direct GeoPackage rows exactly as OGR would write
/// them: every field of `fields` (the union) Integer, Integer64, Real or String without a subtype
/// (OGR clamps Boolean and Int16 values, rounds Float32 ones) or a default value (which an unset
/// field would take), of the same type in every layer that has it (`source_index[k][u]`: layer
/// k's field for union field u, or -1), and every string valid UTF-8 within its field's width
/// (GDAL warns and mends such values).
bool plain_source_values(const Input& in, const OGRFeatureDefn& fields, const std::vector<std::vector<int>>& source_index) {
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    const OGRFieldDefn* f = fields.GetFieldDefn(u);
    const OGRFieldType type = f->GetType();
    if ((type != OFTInteger && type != OFTInteger64 && type != OFTReal && type != OFTString) ||
        f->GetSubType() != OFSTNone || f->GetDefault() != nullptr) {
      return false;
    }
    for (std::size_t k = 0; k < in.table.source_count(); ++k) {
      const int sf = source_index[k][static_cast<std::size_t>(u)];
      if (sf < 0) continue;
      const OGRFieldDefn* own = in.table.definition(k)->GetFieldDefn(sf);
      if (own->GetType() != type || own->GetSubType() != OFSTNone) return false;
    }
  }
  for (const sites::SiteRecord& site : in.table.sites) {
    if (!site.attributes) continue;
    for (int u = 0; u < fields.GetFieldCount(); ++u) {
      const OGRFieldDefn* f = fields.GetFieldDefn(u);
      const int sf = source_index[site.layer][static_cast<std::size_t>(u)];
      if (f->GetType() != OFTString || sf < 0 || !site.attributes->IsFieldSetAndNotNull(sf)) continue;
      const char* text = site.attributes->GetRawFieldRef(sf)->String;
      if (!CPLIsUTF8(text, -1) || (f->GetWidth() > 0 && CPLStrlenUTF8(text) > f->GetWidth())) return false;
    }
  }
  return true;
}

/// Field `sf` of a site's source feature as a row value (plain_source_values' types only).
RowValue source_value(const OGRFeature* feature, int sf) {
  if (sf < 0 || !feature || !feature->IsFieldSetAndNotNull(sf)) return {};
  switch (feature->GetFieldDefnRef(sf)->GetType()) {
    case OFTInteger:
    case OFTInteger64: return RowValue::of(static_cast<std::int64_t>(feature->GetFieldAsInteger64(sf)));
    case OFTReal: return RowValue::of(feature->GetFieldAsDouble(sf));
    default: return {RowValue::Kind::text, 0, 0, feature->GetRawFieldRef(sf)->String};
  }
}

/// A block of regions traced ahead of writing: their rings for OGR features, or their GeoPackage
/// blobs for direct rows.
struct TracedRegions {
  std::vector<Region> regions;
  std::vector<GpkgGeometry> geometries;
};

/// `pair_lengths` (may be null): also the voronoi_edges layer's lengths, from the same pass.
void write_regions(Writer& w, const Input& in, double work, std::vector<PairLength>* pair_lengths) {
  OGRLayer* layer = w.begin_layer("regions", wkbMultiPolygon, work);

  // The source's fields first, as ogr2ogr would copy them; of several source layers (composite
  // sites), the union of their fields by name (a name's first layer gives its type), and then
  // site_layer, the layer of each site.
  OGRFeatureDefn fields("fields");
  // Per source layer: its fields' places in the union (one empty map for a table without a
  // source), and the other way round: the layer's field for each union field (or -1).
  const std::size_t source_layers = std::max<std::size_t>(1, in.table.source_count());
  std::vector<std::vector<int>> field_maps(source_layers), source_index(source_layers);
  for (std::size_t k = 0; k < in.table.source_count(); ++k) {
    const OGRFeatureDefn* source = in.table.definition(k);
    for (int f = 0; source && f < source->GetFieldCount(); ++f) {
      int u = fields.GetFieldIndex(source->GetFieldDefn(f)->GetNameRef());
      if (u < 0) {
        fields.AddFieldDefn(source->GetFieldDefn(f));
        u = fields.GetFieldCount() - 1;
      }
      field_maps[k].push_back(u);
    }
  }
  for (std::size_t k = 0; k < source_layers; ++k) {
    source_index[k].assign(static_cast<std::size_t>(fields.GetFieldCount()), -1);
    for (std::size_t f = 0; f < field_maps[k].size(); ++f) source_index[k][static_cast<std::size_t>(field_maps[k][f])] = static_cast<int>(f);
  }
  std::vector<int> written(static_cast<std::size_t>(fields.GetFieldCount()));
  for (int u = 0; u < fields.GetFieldCount(); ++u) {
    OGRFieldDefn copy(fields.GetFieldDefn(u));
    written[static_cast<std::size_t>(u)] = w.add_field(copy);
  }
  for (auto& map : field_maps) {
    for (int& u : map) u = written[static_cast<std::size_t>(u)];
  }
  int layer_index = -1;
  if (in.composite()) {
    OGRFieldDefn layer_field(unique_field_name("site_layer", &fields).c_str(), OFTString);
    layer_index = w.add_field(layer_field);
  }
  const OGRFeatureDefn* source = &fields;
  OGRFieldDefn fid_field(unique_field_name("site_fid", source).c_str(), OFTInteger64);
  OGRFieldDefn cells_field(unique_field_name("cells", source).c_str(), OFTInteger64);
  OGRFieldDefn area_field(unique_field_name("area_m2", source).c_str(), OFTReal);
  area_field.SetWidth(24);  // up to 5.1e14 with decimals to spare where widths count (shapefiles)
  area_field.SetPrecision(3);
  const int fid_index = w.add_field(fid_field);
  const int cells_index = w.add_field(cells_field);
  const int area_index = w.add_field(area_field);

  StepTrace trace;
  const RingVertices vertices = in.all_ring_vertices ? RingVertices::all : RingVertices::corners;
  // The areas are summed in the tracer's pass over the outline cells, edge by edge.
  std::string device_problem;
  RegionAreaSums area_sums(in.site_count, pair_lengths != nullptr, in.geodesic_device, &device_problem);
  if (!device_problem.empty()) {
    qtmv::tell(in.messages, qtmv::Severity::warning,
         "the regions' geodesics are solved on the CPU instead of cuda:" + std::to_string(in.geodesic_device) + " (" +
             device_problem + ")");
  }
  bool gathered = false;  // RegionTracer's steps, in order: gather (and measure), bucket
  const auto tracer_step = [&](double f) {
    trace(gathered ? "regions' edges bucketed" : "regions' edges gathered, measured");
    gathered = true;
    w.layer_progress(0.4 * f, 1.0);
  };
  const RegionTracer tracer(in.outlines, vertices, tracer_step, &area_sums);
  const std::vector<double> areas = area_sums.areas(in.outlines.cells_per_site);
  if (pair_lengths) *pair_lengths = area_sums.pair_lengths();
  trace("regions' areas");

  w.begin_features();
  // Direct GeoPackage rows: the union's fields, then site_layer, site_fid, cells, area_m2.
  std::vector<int> row_fields = written;
  if (layer_index >= 0) row_fields.push_back(layer_index);
  row_fields.insert(row_fields.end(), {fid_index, cells_index, area_index});
  const std::unique_ptr<GpkgRows> direct =
      plain_source_values(in, fields, source_index) ? w.direct_rows(row_fields) : nullptr;

  // Blocks of regions traced (and made blobs of, for direct rows) on all cores on a helper thread
  // while this one writes the block before: two blocks held, not every region's rings.
  double link_seconds = 0;  // on the helper thread (for the trace)
  const auto link = [&](std::size_t first, std::size_t last) {
    const auto start = std::chrono::steady_clock::now();
    TracedRegions block;
    block.regions.resize(last - first);
    if (direct) block.geometries.resize(last - first);
    FirstException failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(thread_count(0))
    for (std::int64_t s = static_cast<std::int64_t>(first); s < static_cast<std::int64_t>(last); ++s) {
      failure.run([&] {
        Region& region = block.regions[static_cast<std::size_t>(s) - first];
        region = tracer.trace(static_cast<std::int32_t>(s));
        if (direct) {
          region_geometry(region, block.geometries[static_cast<std::size_t>(s) - first]);
          region = {};
        }
      });
    }
    failure.rethrow();
    link_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return block;
  };
  // A row's values in the order of row_fields: the source's (direct rows only; OGR copies them
  // itself), then ours.
  std::vector<RowValue> values(row_fields.size());
  const auto write = [&](std::size_t first, std::size_t last, const TracedRegions& block) {
    for (std::size_t s = first; s < last; ++s) {
      const sites::SiteRecord& site = in.table.sites[s];
      std::size_t v = written.size();
      if (layer_index >= 0) values[v++] = in.layer_of(s);
      values[v++] = fid_value(site.fid);
      values[v++] = RowValue::of(static_cast<std::int64_t>(in.outlines.cells_per_site[s]));
      values[v++] = RowValue::of(areas[s]);
      if (direct) {
        const std::vector<int>& index = source_index[site.layer];
        for (std::size_t u = 0; u < written.size(); ++u) values[u] = source_value(site.attributes.get(), index[u]);
        w.write(*direct, block.geometries[s - first], values.data());
        continue;
      }
      FeaturePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
      const std::vector<int>& field_map = field_maps[site.layer];
      if (site.attributes && !field_map.empty()) {
        if (feature->SetFieldsFrom(site.attributes.get(), field_map.data(), TRUE) != OGRERR_NONE) {
          w.fail("cannot copy the attributes of site " + std::to_string(s));
        }
      }
      for (std::size_t k = written.size(); k < row_fields.size(); ++k) set_value(*feature, row_fields[k], values[k]);
      feature->SetGeometryDirectly(make_multipolygon(block.regions[s - first]));  // empty for a site without cells
      w.write(*feature);
    }
    w.layer_progress(0.4 + 0.6 * static_cast<double>(last) / static_cast<double>(in.site_count), 1.0);
  };
  work_ahead(static_cast<std::size_t>(in.site_count), kRegionBlock, link, write);
  trace("regions traced and written");
  trace.note("of which tracing", link_seconds);
  if (direct) {
    w.guard([&] { direct->finish(); });
    trace("regions' R-tree filled");
  }
  w.end_layer();
  trace("regions layer ended");
}

void write_boundary_cells(Writer& w, const Input& in, double work, std::uint64_t count) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("boundary_cells", wkbPolygon, work, /*per_cell=*/true);
  OGRFieldDefn code_field("code", OFTInteger64);
  OGRFieldDefn fid_field("site_fid", OFTInteger64);
  std::vector<int> fields{w.add_field(code_field), w.add_field(fid_field)};
  if (in.composite()) {
    OGRFieldDefn layer_field("site_layer", OFTString);
    fields.push_back(w.add_field(layer_field));
  }
  w.begin_features();
  CellRows rows(w, layer, fields);
  std::uint64_t done = 0;
  for (const label::OutlineCell& cell : in.outlines.cells) {
    if (!cell.boundary) continue;
    const auto site = static_cast<std::size_t>(cell.site);
    const RowValue values[] = {RowValue::of(static_cast<std::int64_t>(cell.code)), fid_value(in.table.sites[site].fid),
                               in.composite() ? in.layer_of(site) : RowValue{}};
    rows.add(cell.code, level, values);
    if (++done % kProgressEvery == 0) w.layer_progress(static_cast<double>(done), static_cast<double>(count));
  }
  rows.finish();
  w.end_layer();
}

/// `measured` (may be null): the pairs' lengths from the regions' pass (write_regions).
void write_voronoi_edges(Writer& w, const Input& in, double work, const std::vector<PairLength>* measured) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("voronoi_edges", wkbMultiLineString, work);
  OGRFieldDefn a_field("site_a", OFTInteger64);
  OGRFieldDefn b_field("site_b", OFTInteger64);
  OGRFieldDefn length_field("length_m", OFTReal);
  const int a_index = w.add_field(a_field);
  const int b_index = w.add_field(b_field);
  const int length_index = w.add_field(length_field);
  int layer_a_index = -1, layer_b_index = -1;
  if (in.composite()) {
    OGRFieldDefn layer_a("layer_a", OFTString), layer_b("layer_b", OFTString);
    layer_a_index = w.add_field(layer_a);
    layer_b_index = w.add_field(layer_b);
  }

  StepTrace trace;
  const DefaultInitVector<EdgeRef> edges = gather_edges(in.outlines);
  trace("edges gathered");
  std::vector<std::size_t> pair_start;  // where each pair's run of edges begins
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (k == 0 || edges[k].key != edges[k - 1].key) pair_start.push_back(k);
  }
  const std::size_t pairs = pair_start.size();
  pair_start.push_back(edges.size());
  w.layer_progress(0.2, 1.0);

  w.begin_features();
  std::vector<int> row_fields{a_index, b_index, length_index};
  if (in.composite()) row_fields.insert(row_fields.end(), {layer_a_index, layer_b_index});
  const std::unique_ptr<GpkgRows> direct = w.direct_rows(row_fields);
  FeaturePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
  const auto measure = [&](std::size_t first, std::size_t last) {
    std::vector<MeasuredPair> block(last - first);
    FirstException failure;
#pragma omp parallel for schedule(dynamic, 16) num_threads(thread_count(0))
    for (std::int64_t p = static_cast<std::int64_t>(first); p < static_cast<std::int64_t>(last); ++p) {
      failure.run([&] {
        MeasuredPair& out = block[static_cast<std::size_t>(p) - first];
        const std::uint64_t key = edges[pair_start[p]].key;
        std::uint64_t units = 0;  // a pair whose edges are all on the cut is not in `measured`
        if (measured) {
          const auto it = std::lower_bound(measured->begin(), measured->end(), key,
                                           [](const PairLength& m, std::uint64_t k) { return m.key < k; });
          if (it != measured->end() && it->key == key) units = it->units;
        }
        out.lines = link_pair(edges.data() + pair_start[p], edges.data() + pair_start[p + 1], level,
                              measured ? &units : nullptr);
        if (direct) {
          out.geometry.begin(GpkgGeometry::kMultiLineString, static_cast<std::uint32_t>(out.lines.lines.size()));
          for (const auto& line : out.lines.lines) out.geometry.line(line.data(), line.size());
          out.geometry.end();
          out.lines.lines = {};
        }
      });
    }
    failure.rethrow();
    return block;
  };
  const auto write = [&](std::size_t first, std::size_t last, const std::vector<MeasuredPair>& block) {
    for (std::size_t p = first; p < last; ++p) {
      const PairLines& lines = block[p - first].lines;
      const std::uint64_t key = edges[pair_start[p]].key;
      const auto a = static_cast<std::size_t>(key >> 32), b = static_cast<std::size_t>(key & 0xffffffffu);
      // In the order of row_fields (layer_a, layer_b only for composite sites).
      const RowValue values[] = {fid_value(in.table.sites[a].fid), fid_value(in.table.sites[b].fid),
                                 RowValue::of(lines.length_m), in.composite() ? in.layer_of(a) : RowValue{},
                                 in.composite() ? in.layer_of(b) : RowValue{}};
      if (direct) {
        w.write(*direct, block[p - first].geometry, values);
        continue;
      }
      auto* multi = new OGRMultiLineString;
      for (const auto& line : lines.lines) {
        auto* ls = new OGRLineString;
        ls->setNumPoints(static_cast<int>(line.size()), FALSE);
        for (std::size_t k = 0; k < line.size(); ++k) ls->setPoint(static_cast<int>(k), line[k].lon, line[k].lat);
        multi->addGeometryDirectly(ls);
      }
      feature->SetGeometryDirectly(multi);
      for (std::size_t k = 0; k < row_fields.size(); ++k) set_value(*feature, row_fields[k], values[k]);
      w.write(*feature);
    }
    w.layer_progress(0.2 + 0.8 * static_cast<double>(last) / static_cast<double>(pairs), 1.0);
  };
  work_ahead(pairs, kEdgePairBlock, measure, write);
  trace("edges linked and written");
  if (direct) {
    w.guard([&] { direct->finish(); });
    trace("edges' R-tree filled");
  }
  w.end_layer();
  trace("edges layer ended");
}

void write_cells(Writer& w, const Input& in, double work) {
  const int level = in.outlines.level;
  OGRLayer* layer = w.begin_layer("cells", wkbPolygon, work, /*per_cell=*/true);
  OGRFieldDefn code_field("code", OFTInteger64);
  OGRFieldDefn fid_field("site_fid", OFTInteger64);
  OGRFieldDefn distance_field("distance_m", OFTReal);
  OGRFieldDefn boundary_field("boundary", OFTInteger);
  boundary_field.SetSubType(OFSTBoolean);
  std::vector<int> fields{w.add_field(code_field), w.add_field(fid_field), w.add_field(distance_field),
                          w.add_field(boundary_field)};
  if (in.composite()) {
    OGRFieldDefn layer_field("site_layer", OFTString);
    fields.push_back(w.add_field(layer_field));
  }
  w.begin_features();
  CellRows rows(w, layer, fields);
  const Code cells = grid::cell_count(level);
  Code next = 0;
  in.cell_tiles([&](const CellTile& tile) {
    if (tile.first != next) throw std::logic_error("write_vector: the cells layer's tiles are not in code order");
    for (std::uint64_t k = 0; k < tile.count; ++k) {
      const Code code = tile.first + k;
      const std::int32_t site = tile.site[k];
      if (site < 0 || site >= in.site_count) {
        throw std::invalid_argument("write_vector: label " + std::to_string(site) + " of cell " + std::to_string(code) +
                                    " is not a site id (0 to " + std::to_string(in.site_count - 1) + ")");
      }
      const RowValue values[] = {
          RowValue::of(static_cast<std::int64_t>(code)),
          fid_value(in.table.sites[static_cast<std::size_t>(site)].fid),
          tile.distance_m ? RowValue::of(static_cast<double>(tile.distance_m[k])) : RowValue{},
          RowValue::of(std::int64_t{tile.boundary[k] != 0 ? 1 : 0}),
          in.composite() ? in.layer_of(static_cast<std::size_t>(site)) : RowValue{}};
      rows.add(code, level, values);
      if ((code + 1) % kProgressEvery == 0) w.layer_progress(static_cast<double>(code + 1), static_cast<double>(cells));
    }
    next = tile.first + tile.count;
  });
  if (next != cells) throw std::logic_error("write_vector: the cells layer's tiles end before the last cell");
  rows.finish();
  w.end_layer();
}

}  // namespace

std::string check_layer_names(const std::vector<std::string>& layers) {
  std::string valid;
  for (const char* name : kVectorLayerNames) valid += (valid.empty() ? "" : ", ") + std::string(name);
  if (layers.empty()) return "no layer named: choose from " + valid;
  for (const std::string& name : layers) {
    if (std::find(std::begin(kVectorLayerNames), std::end(kVectorLayerNames), name) == std::end(kVectorLayerNames)) {
      return "no layer '" + name + "': choose from " + valid;
    }
  }
  return {};
}

void write_vector(const std::string& path, const label::Outlines& outlines, const CellTileSource& cell_tiles,
                  const sites::SiteTable& table, const VectorOptions& options) {
  // Everything that can be refused is refused before the destination is created.
  if (const std::string problem = check_layer_names(options.layers); !problem.empty()) {
    throw WriteError(path + ": " + problem);
  }
  std::vector<std::string> layers;
  for (const std::string& name : options.layers) {
    if (std::find(layers.begin(), layers.end(), name) == layers.end()) layers.push_back(name);
  }

  if (!grid::is_valid_level(outlines.level)) throw std::invalid_argument("write_vector: bad level " + std::to_string(outlines.level));
  const auto site_count = static_cast<std::int32_t>(table.sites.size());
  if (outlines.site_count != site_count) {
    throw std::invalid_argument("write_vector: the outlines have " + std::to_string(outlines.site_count) +
                                " sites, the table " + std::to_string(site_count));
  }
  StepTrace trace;
  label::check_outlines(outlines);
  trace("outline cells checked");
  if (!(outlines.range == grid::whole_level(outlines.level))) {
    throw std::invalid_argument("write_vector: the outlines hold only codes " + std::to_string(outlines.range.first) +
                                " to " + std::to_string(outlines.range.end) + " of the level");
  }
  const bool want_cells = std::find(layers.begin(), layers.end(), "cells") != layers.end();
  if (want_cells && !cell_tiles) throw std::invalid_argument("write_vector: the cells layer needs the cells' labels");
  const Code cells = grid::cell_count(outlines.level);
  const Input in{outlines, cell_tiles, table, site_count, options.all_ring_vertices, options.geodesic_device,
                 options.messages};
  std::uint64_t boundary_count = 0;
  const auto outline_cells = static_cast<std::int64_t>(outlines.cells.size());
#pragma omp parallel for schedule(static) num_threads(thread_count(0)) reduction(+ : boundary_count)
  for (std::int64_t k = 0; k < outline_cells; ++k) boundary_count += outlines.cells[static_cast<std::size_t>(k)].boundary;

  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(options.driver.c_str());
  if (!driver) {
    GDALAllRegister();
    driver = GetGDALDriverManager()->GetDriverByName(options.driver.c_str());
  }
  if (!driver) throw WriteError(path + ": unknown format '" + options.driver + "'");
  if (!driver->GetMetadataItem(GDAL_DCAP_VECTOR) || !driver->GetMetadataItem(GDAL_DCAP_CREATE)) {
    throw WriteError(path + ": the " + options.driver + " driver cannot create vector datasets");
  }

  // Progress shares: each layer's expected time in microseconds, from the level 11 run of
  // bench/RESULTS.md ("qtmvoronoi end to end") on 2 cores: regions trace and measure every cell, then write a
  // feature per site; boundary_cells and cells cost per row; voronoi_edges gathers over every
  // cell and writes about 3 pairs per site. In GeoPackage through OGR features (not direct rows)
  // the close builds the R-trees of regions and voronoi_edges, about 9 us per feature.
  const double cell_count = static_cast<double>(cells), sites = static_cast<double>(site_count);
  const double outline_count = static_cast<double>(outlines.cells.size());
  const bool rtrees = EQUAL(options.driver.c_str(), "GPKG") && !gpkg_direct_rows_enabled();
  std::vector<double> work;
  double close_work = 1;
  for (const std::string& name : layers) {
    if (name == "regions") work.push_back(1.5 * outline_count + 4 * sites + 1);
    if (name == "boundary_cells") work.push_back(0.4 * static_cast<double>(boundary_count) + 1);
    if (name == "voronoi_edges") work.push_back(1.0 * outline_count + 3 * 2.5 * sites + 1);
    if (name == "cells") work.push_back(0.3 * cell_count + 1);
    if (rtrees && name == "regions") close_work += 9 * sites;
    if (rtrees && name == "voronoi_edges") close_work += 9 * 3 * sites;
  }
  double total = close_work;
  for (double x : work) total += x;

  // Outlives the dataset, which is closed inside it even on a throw.
  gdal::ErrorCapture trap(gdal::ErrorCapture::Warnings::pass_on);
  Writer writer(path, options, trap, total);
  writer.open(driver);
  trace("dataset created");
  // Regions written before voronoi_edges hand on the edges' lengths from their own pass.
  const auto position = [&](const char* name) { return std::find(layers.begin(), layers.end(), name) - layers.begin(); };
  const bool lengths_from_regions = position("regions") < position("voronoi_edges") &&
                                    position("voronoi_edges") < static_cast<std::ptrdiff_t>(layers.size());
  std::vector<PairLength> pair_lengths;
  for (std::size_t k = 0; k < layers.size(); ++k) {
    const std::string& name = layers[k];
    trace.restart();
    if (name == "regions") write_regions(writer, in, work[k], lengths_from_regions ? &pair_lengths : nullptr);
    if (name == "boundary_cells") write_boundary_cells(writer, in, work[k], boundary_count);
    if (name == "voronoi_edges") write_voronoi_edges(writer, in, work[k], lengths_from_regions ? &pair_lengths : nullptr);
    if (name == "cells") write_cells(writer, in, work[k]);
    trace(("layer " + name + ", all told").c_str());
  }
  trace.restart();
  writer.close();
  trace("dataset closed");
  writer.report_done();
}

void write_vector(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const VectorOptions& options) {
  if (!grid::is_valid_level(labels.level)) throw std::invalid_argument("write_vector: bad level " + std::to_string(labels.level));
  if (!labels.site) throw std::invalid_argument("write_vector: no site labels");
  const auto site_count = static_cast<std::int32_t>(table.sites.size());
  const label::Outlines outlines = label::outlines_of_dense(labels.level, labels.site, labels.boundary, site_count);
  const CellTileSource whole = [&](const std::function<void(const CellTile&)>& sink) {
    const Code cells = grid::cell_count(labels.level);
    if (labels.boundary) {
      sink({0, cells, labels.site, labels.distance_m, labels.boundary});
      return;
    }
    std::vector<std::uint8_t> flags(cells);
    for (Code code = 0; code < cells; ++code) flags[code] = is_boundary(labels, code) ? 1 : 0;
    sink({0, cells, labels.site, labels.distance_m, flags.data()});
  };
  write_vector(path, outlines, whole, table, options);
}

}  // namespace qtmv::write
