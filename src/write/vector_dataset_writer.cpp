#include "write/vector_dataset_writer.hpp"

#include <algorithm>
#include <utility>

#include <cpl_conv.h>
#include <cpl_error.h>

#include "common/config_option.hpp"

namespace qtmv::write {

namespace {

using grid::Code;
using grid::LonLat;

constexpr std::uint64_t kTransactionFeatures = 100000;  // features per transaction

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

CPLStringList string_list(const std::vector<std::string>& items) {
  CPLStringList list;
  for (const std::string& item : items) list.AddString(item.c_str());
  return list;
}

}  // namespace

EmptyRows empty_rows_of(const std::string& driver) {
  // GDAL 3.6.2, a MultiPolygon layer (docs/RELIABILITY.md): MapInfo refuses an empty geometry
  // and keeps a null one; these drop both (or drop the empty and refuse the null), silently.
  // MVT and MBTiles write tiles, where a row without a geometry has no place.
  if (EQUAL(driver.c_str(), "MapInfo File")) return EmptyRows::null;
  for (const char* name : {"FlatGeobuf", "PDF", "DXF", "DGN", "OGR_GMT", "Geoconcept", "MVT", "MBTiles"}) {
    if (EQUAL(driver.c_str(), name)) return EmptyRows::left_out;
  }
  return EmptyRows::empty;
}

bool counts_cheaply(const std::string& driver) {
  for (const char* name : {"GPKG", "FlatGeobuf", "ESRI Shapefile", "OpenFileGDB", "MapInfo File"}) {
    if (EQUAL(driver.c_str(), name)) return true;
  }
  return false;
}

RowValue fid_value(std::int64_t fid) { return fid == OGRNullFID ? RowValue{} : RowValue::of(fid); }

void set_value(OGRFeature& feature, int field, const RowValue& value) {
  switch (value.kind) {
    case RowValue::Kind::null: feature.SetFieldNull(field); break;
    case RowValue::Kind::integer: feature.SetField(field, static_cast<GIntBig>(value.integer)); break;
    case RowValue::Kind::real: feature.SetField(field, value.real); break;
    case RowValue::Kind::text: feature.SetField(field, value.text); break;
  }
}

// --- the writer ------------------------------------------------------------------------------

VectorDatasetWriter::VectorDatasetWriter(const std::string& path, const VectorOptions& options,
                                         gdal::ErrorCapture& trap, double total_work)
    : path_(path), options_(options), trap_(trap), total_work_(std::max(total_work, 1.0)) {
  srs_.importFromEPSG(4326);
  srs_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
}

void VectorDatasetWriter::open(GDALDriver* driver) {
  const CPLStringList dsco = string_list(options_.dataset_options);
  if (driver->GetMetadataItem(GDAL_DMD_CONNECTION_PREFIX)) {
    // A database (PG:...) exists already: its driver opens it for update, and cannot create one.
    const char* const drivers[] = {driver->GetDescription(), nullptr};
    dataset_.reset(static_cast<GDALDataset*>(
        GDALOpenEx(path_.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE, drivers, nullptr, nullptr)));
  } else {
    dataset_.reset(driver->Create(path_.c_str(), 0, 0, 0, GDT_Unknown, dsco.List()));
  }
  if (!dataset_) fail("cannot create the dataset");
  check("creating the dataset");
  transactions_ = dataset_->TestCapability(ODsCTransactions) != 0;
  driver_name_ = driver->GetDescription();
  const char* types = driver->GetMetadataItem(GDAL_DMD_CREATIONFIELDDATATYPES);
  if (types) field_types_ = CPLStringList(CSLTokenizeString(types));
}

VectorDatasetWriter::~VectorDatasetWriter() {
  if (!dataset_) return;
  CPLErrorStateBackuper keep_error_state;  // what happens here must not mask the error being thrown
  CPLPushErrorHandler(CPLQuietErrorHandler);
  if (transaction_open_) dataset_->RollbackTransaction();
  dataset_->MarkSuppressOnClose();
  CPLPopErrorHandler();
}

void VectorDatasetWriter::close() {
  layer_name_.clear();
  for (const auto& [name, value] : options_.metadata) {
    if (dataset_->SetMetadataItem(name.c_str(), value.c_str()) != CE_None) fail("cannot set the metadata item " + name);
  }
  if (!options_.metadata.empty()) check("setting the dataset's metadata");
  dataset_.reset();
  check("closing the dataset");
  check_counts();
}

void VectorDatasetWriter::check_counts() {
  if (!counts_cheaply(driver_name_) || layer_rows_.empty()) return;
  const char* const drivers[] = {driver_name_.c_str(), nullptr};
  DatasetPtr written;
  {
    // A file that cannot be opened again (written to /vsistdout/, say) is not checked.
    CPLErrorStateBackuper keep_error_state;
    CPLPushErrorHandler(CPLQuietErrorHandler);
    written.reset(static_cast<GDALDataset*>(
        GDALOpenEx(path_.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers, nullptr, nullptr)));
    CPLPopErrorHandler();
  }
  if (!written) return;
  for (const auto& [name, rows] : layer_rows_) {
    OGRLayer* layer = written->GetLayerByName(name.c_str());
    if (!layer || !layer->TestCapability(OLCFastFeatureCount)) continue;
    const GIntBig count = layer->GetFeatureCount(FALSE);
    if (count < 0 || static_cast<std::uint64_t>(count) == rows) continue;
    layer_name_ = name;
    written.reset();
    fail(std::to_string(rows) + " rows written, but the " + driver_name_ + " file holds " + std::to_string(count) +
         " of them");
  }
}

EmptyRows VectorDatasetWriter::empty_rows() const {
  if (EQUAL(fault_switch("QTMV_FAULT_EMPTY_ROWS").c_str(), "EMPTY")) return EmptyRows::empty;
  return empty_rows_of(driver_name_);
}

void VectorDatasetWriter::warn(const std::string& what) const {
  std::string where = "'" + path_ + "'";
  if (!layer_name_.empty()) where += ", layer " + layer_name_;
  CPLError(CE_Warning, CPLE_AppDefined, "%s: %s", where.c_str(), what.c_str());
}

OGRLayer* VectorDatasetWriter::begin_layer(const char* name, OGRwkbGeometryType type, double work, bool per_cell) {
  layer_name_ = name;
  layer_work_ = work;
  layer_done_ = 0;
  CPLStringList lco = string_list(options_.layer_options);
  if (per_cell && EQUAL(driver_name_.c_str(), "GPKG") && lco.FetchNameValue("SPATIAL_INDEX") == nullptr) {
    lco.SetNameValue("SPATIAL_INDEX", "NO");
  }
  layer_ = dataset_->CreateLayer(name, &srs_, type, lco.List());
  if (!layer_) fail("cannot create the layer");
  layer_rows_.emplace_back(layer_->GetName(), 0);
  check("creating the layer");
  return layer_;
}

int VectorDatasetWriter::add_field(OGRFieldDefn& field) {
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

void VectorDatasetWriter::begin_features() {
  if (transactions_) start_transaction();
}

void VectorDatasetWriter::write(OGRFeature& feature) {
  feature.SetFID(OGRNullFID);  // CreateFeature sets it: let the driver assign the next one
  if (layer_->CreateFeature(&feature) != OGRERR_NONE) fail("cannot write a feature");
  if (trap_.failed()) check("writing a feature");
  count_row();
}

std::unique_ptr<GpkgRows> VectorDatasetWriter::direct_rows(const std::vector<int>& fields) {
  std::unique_ptr<GpkgRows> rows = guard([&] { return GpkgRows::open(*dataset_, *layer_, fields); });
  check("preparing the layer's rows");
  return rows;
}

void VectorDatasetWriter::write(GpkgRows& rows, const GpkgBlob& geometry, const RowValue* values) {
  guard([&] { rows.add(geometry, values); });
  count_row();
}

void VectorDatasetWriter::count_row() {
  ++layer_rows_.back().second;
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

void VectorDatasetWriter::layer_progress(double done, double count) {
  layer_done_ = count > 0 ? layer_work_ * std::min(1.0, done / count) : layer_work_;
  report();
}

void VectorDatasetWriter::end_layer() {
  if (transactions_) commit();
  work_done_ += layer_work_;
  layer_done_ = 0;
  report();
}

void VectorDatasetWriter::report_done() {
  if (options_.progress) options_.progress(1.0, "write");
}

void VectorDatasetWriter::fail(const std::string& what) const {
  std::string message = path_;
  if (!layer_name_.empty()) message += ", layer " + layer_name_;
  message += ": " + what;
  if (trap_.failed()) message += ": " + trap_.take();
  throw WriteError(message);
}

void VectorDatasetWriter::check(const std::string& what) const {
  if (trap_.failed()) fail(what);
}

void VectorDatasetWriter::start_transaction() {
  if (dataset_->StartTransaction(FALSE) != OGRERR_NONE) fail("cannot start a transaction");
  transaction_open_ = true;
  in_transaction_ = 0;
}

void VectorDatasetWriter::commit() {
  transaction_open_ = false;
  if (dataset_->CommitTransaction() != OGRERR_NONE) fail("cannot commit a transaction");
  check("committing a transaction");
  in_transaction_ = 0;
}

void VectorDatasetWriter::report() {
  if (!options_.progress) return;
  const double fraction = std::min(1.0, (work_done_ + layer_done_) / total_work_);
  if (!options_.progress(fraction, "write")) throw Interrupted();
}

// --- a per-cell layer's rows ----------------------------------------------------------------

CellRows::CellRows(VectorDatasetWriter& w, OGRLayer* layer, std::vector<int> fields)
    : w_(w), fields_(std::move(fields)), direct_(w.direct_rows(fields_)) {
  if (!direct_) feature_ = cell_feature(layer);
}

CellPolygons CellRows::begin(std::vector<Code> codes, int level) const {
  CellPolygons block;
  const std::size_t n = codes.size();
  if (direct_) {
    block.blobs.resize(n * CellPolygons::kBlobStride);
    block.blob_sizes.resize(n);
    block.envelopes.resize(n);
  } else {
    block.rings.resize(n * grid::kMaxPolygonCorners);
    block.corners.resize(n);
  }
  block.level = level;
  block.codes = std::move(codes);
  return block;
}

void CellRows::make(CellPolygons& block, std::size_t k) const {
  LonLat ring[grid::kMaxPolygonCorners];
  const int corners = grid::cell_polygon(grid::cell_of(block.codes[k], block.level), block.level, ring);
  if (!direct_) {
    std::copy(ring, ring + corners, block.rings.begin() + static_cast<std::ptrdiff_t>(k * grid::kMaxPolygonCorners));
    block.corners[k] = static_cast<std::uint8_t>(corners);
    return;
  }
  thread_local GpkgGeometry polygon;  // the thread's, from cell to cell
  polygon.begin(GpkgGeometry::kPolygon, 1);
  polygon.ring(ring, static_cast<std::size_t>(corners));
  polygon.end();
  std::copy(polygon.data(), polygon.data() + polygon.size(),
            block.blobs.begin() + static_cast<std::ptrdiff_t>(k * CellPolygons::kBlobStride));
  block.blob_sizes[k] = static_cast<std::uint32_t>(polygon.size());
  block.envelopes[k] = polygon.envelope();
}

void CellRows::add(const CellPolygons& block, std::size_t k, const RowValue* values) {
  if (direct_) {
    const GpkgBlob blob{block.blobs.data() + k * CellPolygons::kBlobStride, block.blob_sizes[k], block.envelopes[k]};
    w_.write(*direct_, blob, values);
    return;
  }
  set_ring(*feature_, block.rings.data() + k * grid::kMaxPolygonCorners, block.corners[k]);
  for (std::size_t f = 0; f < fields_.size(); ++f) set_value(*feature_, fields_[f], values[f]);
  w_.write(*feature_);
}

void CellRows::end_block() {
  if (direct_) w_.guard([&] { direct_->flush(); });
}

void CellRows::finish() {
  if (direct_) w_.guard([&] { direct_->finish(); });
}

}  // namespace qtmv::write
