// The first stage of a run: every check that can fail before any work (options, output format,
// destination, memory, disk space), and what they decide for the stages after it. The CUDA
// devices are counted while the sites are read, and checked and settled then (settle_devices).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "label/auto_device.hpp"
#include "label/label_options.hpp"
#include "pipeline/output_format.hpp"
#include "pipeline/voronoi_error.hpp"
#include "pipeline/voronoi_options.hpp"
#include "write/cell_labels.hpp"

namespace qtmv::pipeline {

/// What a run will do, decided before any work.
struct RunPlan {
  int level = 0;
  std::string level_note;        ///< why the level, when the run chose it (a lon/lat raster's pixels)
  OutputFormat format;           ///< the driver and whether it writes a raster
  write::VectorOptions vector;   ///< the vector writer's options (progress set by the write stage)
  write::RasterOptions raster;   ///< the raster writer's options (likewise)
  /// The labeller's options: the outline pass (label_outlines), the raster's labelling session
  /// and the tiles of the cells layer (label_cells).
  label::LabelOptions label;
  bool cells_layer = false;  ///< vector output with the cells layer: every cell's labels, in tiles
  /// A tile job's tile (-tile K/N), its range in label.range; 0: a whole run or a merge.
  int tile_index = 0, tile_count = 0;
  /// A tile job that writes its part of the output (-part): vector (vector.part: its tile's
  /// rows) or a raster (raster.first_row, part_rows: a band of pixel rows; label.range is then
  /// the whole level, every site read).
  bool part = false;
  /// A merge's tile product files (tile_product_files of -merge); empty: the run labels.
  std::vector<std::string> merge_files;
  /// Ends of the read and label stages' slices of the run's progress (fractions 0..1); the label
  /// stage's is set by settle_devices.
  double read_end = 0, label_end = 0;
  /// Usable CUDA devices on this host: -1 until settle_devices (they are counted while the
  /// sites are read: label::DeviceStartup).
  int cuda_devices = -1;
};

/// Checks the options against the destination and this host, and plans the run; throws
/// VoronoiError naming the option, the destination or the shortage. Nothing is written.
RunPlan plan_run(const std::string& destination, const VoronoiOptions& options);

/// The plan of a tile job (options.tile_count > 0): the labeller's options for its tile's codes;
/// the destination is a tile product, not a dataset. Throws VoronoiError naming the option.
RunPlan plan_tile_job(const std::string& destination, const VoronoiOptions& options);

/// Throws VoronoiError naming -device when it names CUDA devices that the host's `cuda_devices`
/// do not include.
void check_devices(const RunPlan& plan, int cuda_devices);

/// -device auto's estimate for this plan (label/auto_device.hpp): the level, what is written (the
/// outlines, the cells layer's every cell, a raster's pixels), a tile job's share, the threads;
/// `sites` and `candidates` (the labeller's input: points, arcs, fixed cells) 0 before the read.
label::AutoDevice estimate_auto_device(const RunPlan& plan, std::uint64_t sites, std::uint64_t candidates);

/// -device auto settled once the sites are read: plan.label.device becomes "cuda" when `choice`
/// picks a GPU and `cuda_devices` (counted only then) has one, else "cpu" (before settle_devices).
void settle_auto_device(RunPlan& plan, const label::AutoDevice& choice, int cuda_devices);

/// The summary's device for a run that -device auto settled: "auto: cpu (2 threads), 2.2 M cells
/// of work, below the GPU's start (4.7 M on 2 threads)"; `device` is where the labelling ran.
std::string auto_device_summary(const std::string& device, const label::AutoDevice& choice, int cuda_devices);

/// check_devices, then what the devices decide: the labeller's tiles (the CPU's are smaller, so
/// that an interrupt is seen within a second) and the label stage's slice of the progress.
void settle_devices(RunPlan& plan, const VoronoiOptions& options, int cuda_devices);

/// Throws VoronoiError, with the estimate, when estimate_run_memory(plan, sites) is more than the
/// run may use: memory_limit_bytes (VoronoiOptions), or 80% of RAM when 0. `sites`: 0 before the
/// read (the estimate then takes one).
void check_run_memory(const RunPlan& plan, std::uint64_t memory_limit_bytes, std::uint64_t sites);

/// Host memory (bytes) the run's largest products take: for vector output the outline cells (an
/// estimate from the site count: they grow 2x per level) and the labeller's tiles; for a raster
/// the labelling session's jump table and the writer's strip, which follow the strip size, not
/// the cells (the candidates and the rest of the tree, which grow with the sites, are not
/// counted, as for vector output).
std::uint64_t estimate_run_memory(const RunPlan& plan, std::uint64_t sites);

}  // namespace qtmv::pipeline
