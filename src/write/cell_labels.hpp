// What the writers take from the labeller: plain per-cell arrays, and their options.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/run_context.hpp"
#include "grid/qtm.hpp"

namespace qtmv::write {

/// The labeller's output for every cell of one level, indexed by cell code (0 .. 8 * 4^level - 1).
struct CellLabels {
  int level = 0;                           ///< QTM level (0..24)
  const std::int32_t* site = nullptr;      ///< site id of each cell (an index into the site table)
  const float* distance_m = nullptr;       ///< distance to the site (metres); null when not computed
  const std::uint8_t* boundary = nullptr;  ///< 1 on boundary cells, else 0; null when not computed
};

/// Labels on demand, for a writer that streams (the raster writer, strip by strip): it asks for
/// the labels of what it is about to write, into its own buffers, and never holds a level's.
/// The pipeline's source is the labeller's session (label/label_session.hpp); DenseLabelSource
/// hands over arrays a caller already has.
class CellLabelSource {
 public:
  virtual ~CellLabelSource() = default;
  virtual int level() const = 0;
  /// Whether distances can be asked for (distance_m may be non-null below).
  virtual bool has_distance() const = 0;
  /// Codes [first, first + count): site ids (indices into the site table), distances (metres;
  /// null: not wanted) and boundary flags (0/1), entry k for code first + k.
  virtual void label_range(grid::Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                           std::uint8_t* boundary) const = 0;
  /// The same for codes[0..count) (sorted, without repeats), entry k for codes[k].
  virtual void label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                           std::uint8_t* boundary) const = 0;
  /// The labels of the cells that hold the points (lon[k], lat[r]), r < rows, k < count (degrees:
  /// a lon/lat raster's rows of pixel centres; lat in [-90, 90], lon in [-180, 180) ascending),
  /// entry r * count + k; each point's cell is grid::lonlat_to_code's. By default the points'
  /// codes, then label_codes of the distinct ones; the labeller's session finds them along each
  /// parallel through its tree's leaves instead.
  virtual void label_parallels(const double* lat, int rows, const double* lon, std::size_t count, std::int32_t* site,
                               float* distance_m, std::uint8_t* boundary) const {
    const std::size_t points = static_cast<std::size_t>(rows) * count;
    std::vector<grid::Code> codes(points);
    for (int r = 0; r < rows; ++r) {
      const grid::ParallelCells parallel(lat[r], level());
      for (std::size_t k = 0; k < count; ++k) codes[static_cast<std::size_t>(r) * count + k] = parallel.code(lon[k]);
    }
    std::vector<grid::Code> distinct = codes;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    std::vector<std::int32_t> sites(distinct.size());
    std::vector<float> metres(distance_m ? distinct.size() : 0);
    std::vector<std::uint8_t> flags(boundary ? distinct.size() : 0);
    label_codes(distinct.data(), distinct.size(), sites.data(), distance_m ? metres.data() : nullptr,
                boundary ? flags.data() : nullptr);
    for (std::size_t p = 0; p < points; ++p) {
      const std::size_t k = static_cast<std::size_t>(std::lower_bound(distinct.begin(), distinct.end(), codes[p]) - distinct.begin());
      site[p] = sites[k];
      if (distance_m) distance_m[p] = metres[k];
      if (boundary) boundary[p] = flags[k];
    }
  }
};

/// The labels of one range of codes [first, first + count) (valid during the call that hands
/// it over).
struct CellTile {
  grid::Code first = 0;
  std::uint64_t count = 0;
  const std::int32_t* site = nullptr;      ///< site id of each cell
  const float* distance_m = nullptr;       ///< metres; null when not computed
  const std::uint8_t* boundary = nullptr;  ///< 1 on boundary cells, else 0
};

/// Hands the labels of every cell of a level to `sink`, tile by tile in code order: the cells
/// layer is one row per cell, written as the tiles come (the pipeline labels them again; a
/// caller with dense labels hands them over at once).
using CellTileSource = std::function<void(const std::function<void(const CellTile&)>& sink)>;

/// The boundary flag of cell `code`: the labeller's when it computed them, else its rule (one of
/// the three edge neighbours has another site).
inline bool is_boundary(const CellLabels& labels, grid::Code code) {
  if (labels.boundary) return labels.boundary[code] != 0;
  grid::Code nb[3];
  grid::neighbours(code, labels.level, nb);
  const std::int32_t site = labels.site[code];
  return labels.site[nb[0]] != site || labels.site[nb[1]] != site || labels.site[nb[2]] != site;
}

/// CellLabels as a CellLabelSource (boundary flags from is_boundary when labels.boundary is null).
class DenseLabelSource : public CellLabelSource {
 public:
  explicit DenseLabelSource(const CellLabels& labels) : labels_(labels) {}
  int level() const override { return labels_.level; }
  bool has_distance() const override { return labels_.distance_m != nullptr; }
  void label_range(grid::Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    for (std::uint64_t k = 0; k < count; ++k) put(first + k, k, site, distance_m, boundary);
  }
  void label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    for (std::size_t k = 0; k < count; ++k) put(codes[k], k, site, distance_m, boundary);
  }
  void label_parallels(const double* lat, int rows, const double* lon, std::size_t count, std::int32_t* site,
                       float* distance_m, std::uint8_t* boundary) const override {
    for (int r = 0; r < rows; ++r) {
      const grid::ParallelCells parallel(lat[r], labels_.level);
      const std::size_t at = static_cast<std::size_t>(r) * count;
      for (std::size_t k = 0; k < count; ++k) put(parallel.code(lon[k]), at + k, site, distance_m, boundary);
    }
  }

 private:
  void put(grid::Code code, std::size_t k, std::int32_t* site, float* distance_m, std::uint8_t* boundary) const {
    site[k] = labels_.site[code];
    if (distance_m) distance_m[k] = labels_.distance_m[code];
    if (boundary) boundary[k] = is_boundary(labels_, code) ? 1 : 0;
  }
  CellLabels labels_;
};

// The run's plumbing (common/run_context.hpp): a progress callback returning false stops the
// writing with Interrupted, and what was written is removed.
using qtmv::Interrupted;
using qtmv::MessageSink;
using qtmv::ProgressFunc;

/// A writing error: the message names the destination, the layer or band, and GDAL's reason.
class WriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a vector output holds: the options a caller of the pipeline gives.
struct VectorLayers {
  /// Layers to write, from regions, boundary_cells, voronoi_edges, cells.
  std::vector<std::string> layers{"regions", "boundary_cells", "voronoi_edges"};
  std::vector<std::string> dataset_options;  ///< -dsco NAME=VALUE
  std::vector<std::string> layer_options;    ///< -lco NAME=VALUE
  /// -vertices: which vertices the regions' rings keep where they run along a parallel
  /// (RingVertices in region_tracer.hpp). automatic (-vertices not given) is all: every cell
  /// vertex, so that readers of geodesic edges (PostGIS geography, BigQuery, S2) get the region
  /// drawn and its area_m2; corners: the runs' ends only, for planar readers alone.
  enum class Vertices { automatic, corners, all };
  Vertices ring_vertices = Vertices::automatic;
  bool all_ring_vertices() const { return ring_vertices != Vertices::corners; }
};

/// Vector output (any OGR driver), all in EPSG:4326.
struct VectorOptions : VectorLayers {
  std::string driver = "GPKG";  ///< OGR driver short name
  ProgressFunc progress;        ///< may be empty
  /// The CUDA device (the process's ordinal) that solves the regions' geodesics (their areas,
  /// the Voronoi edges' lengths); -1: the CPU. The same values either way: a device that cannot be used leaves
  /// them to the CPU, with a warning to `messages`.
  int geodesic_device = -1;
  MessageSink messages;  ///< may be empty
  /// A part of a partitioned output (a tile job's, -tile K/N -part): the outlines hold one range
  /// of the level (whole rows); its regions are cut at the range's edges (region_tracer.hpp:
  /// with_range_edges) and only the sites with cells in it get a row. Not voronoi_edges.
  bool part = false;
  /// Items of the dataset's metadata (NAME, VALUE), set before it is closed: a part's identity,
  /// which the index of the parts checks. Empty for a whole run.
  std::vector<std::pair<std::string, std::string>> metadata;
};

/// A band of a raster output (-bands): the FID of the cell's site, its boundary flag (0/1), its
/// distance to the site (metres).
enum class RasterBand { fid, boundary, distance };

/// What a raster output holds: the options a caller of the pipeline gives.
struct RasterGrid {
  enum class Layout {
    qtm,     ///< the QTM-coded raster: column j, row octant * 2^L + i
    lonlat,  ///< a georeferenced EPSG:4326 grid over the globe
  };
  Layout layout = Layout::qtm;
  double x_resolution = 0, y_resolution = 0;  ///< -tr (degrees); 0: from -ts or the default
  int width = 0, height = 0;                  ///< -ts (pixels); 0: from -tr or the default
  /// -ot: the bands' data type, one of Byte, UInt16, Int16, UInt32, Int32, Float32, Float64
  /// (any case); empty: the default of raster_writer.hpp.
  std::string data_type;
  std::vector<std::string> creation_options;  ///< -co NAME=VALUE
  /// -bands: the bands written, in this order, each once (write/raster_bands.hpp); empty: fid,
  /// boundary and distance (distance only where the labels have distances).
  std::vector<RasterBand> bands;
};

/// Raster output (any GDAL raster driver with Create or CreateCopy).
struct RasterOptions : RasterGrid {
  std::string driver = "GTiff";  ///< GDAL driver short name
  ProgressFunc progress;         ///< may be empty
  /// Bytes the writer's buffers for one strip of rows may take (its pixels and their labels);
  /// 0: kDefaultStripBytes. At least one row is written at a time, whatever this says.
  std::uint64_t strip_bytes = 0;
  /// A part of the raster (a tile job's, -tile K/N -part): only its rows [first_row, first_row +
  /// part_rows) (pixels, from the top) are written, as a raster of part_rows rows whose
  /// geotransform starts at its first row; the pixels are those rows of the whole raster.
  /// part_rows 0: the whole raster.
  int first_row = 0, part_rows = 0;
  /// Items of the dataset's metadata (NAME, VALUE), set with its own: a part's identity, which
  /// the index of the parts checks. Empty for a whole run.
  std::vector<std::pair<std::string, std::string>> metadata;
};

}  // namespace qtmv::write
