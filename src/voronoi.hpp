// The pipeline: sites from an OGR source -> labels for every cell of a QTM level -> a vector or
// raster dataset. The library side of the qtmvoronoi tool, in the style of GDAL's *_lib.cpp
// utilities: an options struct, a progress callback that can stop the run, a message sink;
// failures are exceptions (never exit()), and the destination is written all or nothing.
#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/run_context.hpp"
#include "label/labeller.hpp"
#include "pipeline/voronoi_error.hpp"
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
  int level = label::kDefaultLevel;  ///< QTM level of the whole run (0..24)
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
  write::RasterGrid raster;    ///< -raster, -tr (degrees), -ts (pixels), -co
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
  /// -merge: the tile products of all tile_count tile jobs (files, or directories of *.qtmt
  /// files), joined instead of labelling. The source and reading options must be the tile jobs';
  /// the destination is then exactly a whole run's. Vector output only.
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



/// The output driver and kind a run would use: options.format (-of), or the first GDAL driver
/// whose extensions (GDAL_DMD_EXTENSIONS) list the destination's and that can create vectors
/// (preferred) or rasters, as `kind` allows. Throws VoronoiError.
struct OutputFormat {
  std::string driver;
  bool raster = false;
};
OutputFormat choose_output_format(const std::string& destination, const std::string& format, OutputKind kind);

/// Runs the whole pipeline from `source` (any OGR dataset name) to `destination` (with
/// options.tile_count, a tile job's product; with options.merge, from tile products). Checks the
/// options, the destination (an existing one is an error unless options.overwrite) and the
/// memory before any work; writes into a temporary directory beside the destination and renames
/// the result into place after a clean close (/vsi* destinations are written directly).
/// Throws VoronoiError, or Interrupted when the progress callback returned false; on any throw
/// the destination is untouched and the temporary files are gone.
VoronoiSummary run_voronoi(const std::string& source, const std::string& destination, const VoronoiOptions& options);

}  // namespace qtmv
