// The vector dataset being written (vector_writer.hpp): its layers, fields, transactions,
// progress and errors, shared by the layer writers; and the rows of a per-cell layer.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include "common/default_init_allocator.hpp"
#include "gdal/error_capture.hpp"
#include "grid/qtm.hpp"
#include "sites/site_table.hpp"
#include "write/cell_labels.hpp"
#include "write/gpkg_rows.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::write {

constexpr std::uint64_t kProgressEvery = 1024;  // features between progress calls

struct DatasetCloser {
  void operator()(GDALDataset* dataset) const { GDALClose(dataset); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

using sites::FeaturePtr;

/// A site's FID as a field value: null for OGRNullFID.
RowValue fid_value(std::int64_t fid);

void set_value(OGRFeature& feature, int field, const RowValue& value);

/// Whether the driver's files tell their layers' feature counts cheaply (a header or a table
/// of counts), so that a closed dataset's layers can be checked against the rows written.
bool counts_cheaply(const std::string& driver);

/// The dataset being written: layers, fields, transactions, progress and errors.
class VectorDatasetWriter {
 public:
  VectorDatasetWriter(const std::string& path, const VectorOptions& options, gdal::ErrorCapture& trap,
                      double total_work);

  void open(GDALDriver* driver);

  VectorDatasetWriter(const VectorDatasetWriter&) = delete;
  VectorDatasetWriter& operator=(const VectorDatasetWriter&) = delete;

  /// Left without close(): a failure or an interrupt, and the file will be removed. Nothing of
  /// it needs finishing (a GeoPackage would build its deferred spatial index at close, which
  /// takes many seconds on millions of features), so drop the open transaction and ask GDAL
  /// not to flush.
  ~VectorDatasetWriter();

  /// Closes the dataset; throws if GDAL reported any error meanwhile, or if a layer of a driver
  /// that counts_cheaply holds other than as many features as rows were written.
  void close();

  /// How the current driver takes a row with an empty geometry (fault injection for the tests:
  /// the configuration option QTMV_FAULT_EMPTY_ROWS=EMPTY writes empties to every driver).
  EmptyRows empty_rows() const;
  const std::string& driver_name() const { return driver_name_; }

  /// A warning naming the file and the current layer ("'x.fgb', layer regions: ...").
  void warn(const std::string& what) const;

  /// Creates a layer; `work` is its share of the progress (features it will write, about).
  /// `per_cell`: a layer of millions of cell polygons (boundary_cells, cells), which gets no
  /// GeoPackage spatial index unless the layer options ask for one (see the header).
  OGRLayer* begin_layer(const char* name, OGRwkbGeometryType type, double work, bool per_cell = false);

  /// Adds a field; returns its index in the layer (drivers may launder its name). A type the
  /// driver does not list (a list in a shapefile) becomes String with a warning, as ogr2ogr does:
  /// OGRFeature::SetFieldsFrom then writes the values as text.
  int add_field(OGRFieldDefn& field);

  /// Starts writing features (after the fields are made).
  void begin_features();

  void write(OGRFeature& feature);

  /// Rows straight into the current layer's GeoPackage table (see gpkg_rows.hpp); null where
  /// that does not apply.
  std::unique_ptr<GpkgRows> direct_rows(const std::vector<int>& fields);

  /// Adds a row to `rows` (direct rows of the current layer) and books it.
  void write(GpkgRows& rows, const GpkgBlob& geometry, const RowValue* values);

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
  void count_row();

  /// Reports progress within the layer: `done` of `count` features.
  void layer_progress(double done, double count);

  void end_layer();

  /// The last report, once the dataset is closed (too late to interrupt).
  void report_done();

  [[noreturn]] void fail(const std::string& what) const;

 private:
  void check(const std::string& what) const;
  /// After the close: each layer's feature count against its rows (counts_cheaply drivers).
  void check_counts();
  void start_transaction();
  void commit();
  void report();

  std::string path_;
  const VectorOptions& options_;
  gdal::ErrorCapture& trap_;
  OGRSpatialReference srs_;
  DatasetPtr dataset_;
  OGRLayer* layer_ = nullptr;
  std::string layer_name_, driver_name_;
  std::vector<std::pair<std::string, std::uint64_t>> layer_rows_;  ///< each layer's rows written
  CPLStringList field_types_;  ///< the driver's GDAL_DMD_CREATIONFIELDDATATYPES (empty: not stated)
  bool transactions_ = false, transaction_open_ = false;
  std::uint64_t in_transaction_ = 0, since_progress_ = 0;
  double total_work_, work_done_ = 0, layer_work_ = 0, layer_done_ = 0;
};

/// A block of cells' polygons made ahead of their rows (CellRows::begin, make), in the
/// form the rows take: GeoPackage blobs for direct rows, else the rings for OGR features.
struct CellPolygons {
  /// The largest cell's blob (bytes): a pole cell's ring of 4 corners, closed.
  static constexpr std::size_t kBlobStride = 8 + 32 + 9 + 4 + 16 * (grid::kMaxPolygonCorners + 1);

  int level = 0;                           ///< the cells' QTM level
  std::vector<grid::Code> codes;           ///< the cells, in the order of their rows
  DefaultInitVector<unsigned char> blobs;  ///< direct rows: cell k's blob at k * kBlobStride
  std::vector<std::uint32_t> blob_sizes;   ///< direct rows
  std::vector<GpkgEnvelope> envelopes;     ///< direct rows
  std::vector<grid::LonLat> rings;         ///< OGR: cell k's ring at k * kMaxPolygonCorners
  std::vector<std::uint8_t> corners;       ///< OGR: its corners
};

/// Where a per-cell layer's polygons go: straight into its GeoPackage table (GpkgRows), or
/// else through OGR, one reused feature at a time. Values come in the order of `fields`.
class CellRows {
 public:
  CellRows(VectorDatasetWriter& w, OGRLayer* layer, std::vector<int> fields);

  /// A block for cells `codes` of QTM level `level`, sized, its polygons still to make (any
  /// thread, while this one writes the rows of the block before).
  CellPolygons begin(std::vector<grid::Code> codes, int level) const;

  /// Makes the polygon of cell k of `block` (any thread, any cell at once).
  void make(CellPolygons& block, std::size_t k) const;

  /// Adds the row of cell k of `block`, with its values.
  void add(const CellPolygons& block, std::size_t k, const RowValue* values);

  /// After the block's last add(), before the block goes: writes the rows that point at it.
  void end_block();

  /// After the last add(), before the layer ends.
  void finish();

 private:
  VectorDatasetWriter& w_;
  std::vector<int> fields_;
  std::unique_ptr<GpkgRows> direct_;
  FeaturePtr feature_;
};

}  // namespace qtmv::write
