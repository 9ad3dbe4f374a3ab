// What a caller of the pipeline gives and gets back: the options of a run (VoronoiOptions, each
// option once) and what it did (VoronoiSummary). Plain data (no GDAL, nothing of the labeller but
// its enums), below the pipeline's stages, which take it, and the API (voronoi.hpp), which runs it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/run_context.hpp"
#include "label/label_options.hpp"
#include "sites/site_options.hpp"
#include "write/cell_labels.hpp"

namespace qtmv {

// The run's plumbing (common/run_context.hpp): MessageSink, Severity, and ProgressFunc, called
// here with the fraction of the whole run done (0..1) and the current stage ("read", "label",
// "write", or a finer name a part reports); returning false stops the run with Interrupted.

/// Vector or raster output; automatic lets the driver decide (vector when it writes both).
enum class OutputKind { automatic, vector, raster };

/// The options of a run, each given once: every part's options are built from these, and
/// nothing a caller sets is overwritten.
struct VoronoiOptions {
  /// kLevelFromOutput (-level not given): label::kDefaultLevel, or for a lon/lat raster with
  /// -tr or -ts the level whose cells are about four times finer than a pixel (pixel_level).
  static constexpr int kLevelFromOutput = -1;
  int level = kLevelFromOutput;  ///< QTM level of the whole run (0..24), or kLevelFromOutput
  label::Rule rule = label::Rule::exact;  ///< -distance: the distance rule, reading and labelling
  sites::SourceOptions read;  ///< what to read and how (-l, -where, -sql, -s_srs, -oo, -edges, ...)
  std::string device = "auto";  ///< -device auto|cpu|cuda|cuda:N
  label::Algorithm algorithm = label::Algorithm::automatic;  ///< -algorithm
  int threads = 0;              ///< -threads: CPU threads; 0: all
  /// GDAL driver short name (-of); empty: guessed from the destination's extension.
  std::string format;
  /// -layers forces vector output, -raster raster output.
  OutputKind kind = OutputKind::automatic;
  write::VectorLayers vector;  ///< -layers, -dsco, -lco
  write::RasterGrid raster;    ///< -raster, -tr (degrees), -ts (pixels), -ot, -co, -bands
  bool overwrite = false;      ///< replace an existing destination
  /// Refuse, before any work, an output larger than the free space of its directory
  /// (write/output_size.hpp); the GDAL configuration option CHECK_DISK_FREE_SPACE=NO also
  /// turns this off.
  bool check_disk_space = true;
  /// Host memory (bytes) the run may use for its products (vector output's outline cells, a
  /// raster's strips: a quarter of it, at most 64 MiB, per strip) and the labeller's tiles; 0: 80%
  /// of physical RAM.
  std::uint64_t memory_limit_bytes = 0;
  /// -tile K/N: a tile job. Only tile `tile_index` (1..tile_count) of the level split in
  /// tile_count parts (grid::tile_range: whole octant rows, in code order) is labelled, and its
  /// products are written to the destination as a tile product (pipeline/tile_product.hpp)
  /// instead of a dataset; the output options are not used. 0: a whole run.
  int tile_index = 0;
  int tile_count = 0;
  /// -part, with -tile K/N: the tile job writes its part of the vector output instead of a tile
  /// product: a GeoPackage with the layers' rows of its tile (regions cut at the tile's edges,
  /// rows only for the sites with cells in it; boundary_cells and cells, per cell, exactly the
  /// whole run's rows of the tile); not voronoi_edges. With a raster destination, a raster part:
  /// a band of the whole raster's rows (pipeline/raster_part_index.hpp), every site read. -merge
  /// of the parts with format "VRT" (or a .vrt destination) writes their index
  /// (pipeline/part_index.hpp).
  bool part = false;
  /// -merge: the tile products of all tile_count tile jobs (files, or directories of *.qtmt
  /// files), joined instead of labelling. The source and reading options must be the tile jobs';
  /// the destination is then exactly a whole run's. Vector output only. With format "VRT" (or a
  /// .vrt destination): the parts of -tile K/N -part jobs (files, or directories of *.gpkg and
  /// *.tif files), indexed by an OGR VRT (a GDAL VRT for raster parts); the source is not read.
  std::vector<std::string> merge;
  ProgressFunc progress;   ///< may be empty
  MessageSink messages;    ///< warnings, informative lines and the closing summary; may be empty
};

/// What a run did: counts and wall-clock seconds per stage.
struct VoronoiSummary {
  std::string driver;              ///< GDAL driver written with
  bool raster = false;             ///< raster (true) or vector output
  std::uint64_t features = 0;      ///< features read from the source (after -where)
  std::uint64_t sites = 0;         ///< features kept as sites
  std::uint64_t skipped = 0;       ///< features skipped
  std::uint64_t invalid_polygons = 0;   ///< features with an invalid polygon (named in warnings)
  std::uint64_t repaired_polygons = 0;  ///< of them, repaired by -makevalid
  int level = 0;                   ///< QTM level
  std::uint64_t cells = 0;         ///< 8 * 4^level
  std::uint64_t sites_without_cell = 0;  ///< sites that got no cell in the labels
  std::string device;              ///< where the labelling ran (or which tile products were merged)
  int tile_index = 0, tile_count = 0;  ///< a tile job's tile (-tile K/N); 0: a whole run
  double read_seconds = 0;         ///< reading and rasterising the sites (s)
  double rasterise_seconds = 0;    ///< of read_seconds, tracing and filling the sites' cells (s)
  double prepare_seconds = 0;      ///< the labeller's candidates and tree (s)
  double label_seconds = 0;        ///< labelling every cell, boundaries included (s); a raster's strips too
  double write_seconds = 0;        ///< regions/rasters, the dataset, its close and rename (s), less that
  double total_seconds = 0;        ///< the whole run (s)
  /// One line: sites read and skipped (and invalid polygons), level, cells, device, time per stage.
  std::string line() const;
};

}  // namespace qtmv
