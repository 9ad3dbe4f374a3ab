// -device auto's choice: the CPU when the run's labelling work on the CPU takes less time than a
// GPU's fixed start, a GPU beyond. The work is estimated from plain numbers (the level, the sites
// and their candidates, what is written, the threads) in "cells": the time one CPU thread takes
// to label a cell in dense tiles. The constants come from bench/RESULTS.md's runs on 16-core
// H100/H200 hosts; the GPU's own labelling time, a small fraction of the CPU's, is left out.
#pragma once

#include <cstdint>
#include <string>

namespace qtmv::label {

/// One CPU thread's time to label a cell in dense tiles (seconds): 135 233 points at level 13
/// (537 M cells, dense tiles) took 5.28 s on 16 threads, 157 ns a cell a thread.
constexpr double kCpuSecondsPerCell = 150e-9;
/// The CPU threads the estimate counts at most: beyond 16 a small run's labelling gets no faster
/// (on the 64-core, 4-GPU host, country centres L12 took 0.95 s to label on 64 threads, 0.07 s on
/// one H200, and centres L13 0.33 s on a 16-core host: bench/RESULTS.md, session 20).
constexpr int kCpuScalingThreads = 16;
/// The outline pass's work per outline cell (the leaves it visits, the cells it labels around
/// each), in cells: country centres at level 13 (1.7 M outline cells) took 0.13-0.15 s on 16 threads.
constexpr double kCellsPerOutlineCell = 10;
/// The host tree's work per candidate (a point, an arc of a line or ring, a fixed cell), in cells,
/// which a GPU builds on the device instead: 1 M points at level 10 took 9.1 s to prepare on one
/// thread of the 2-core machine, 60 cells a point.
constexpr double kCellsPerCandidate = 60;
/// What a GPU run pays and a CPU run does not (seconds): the driver's start, the context and its
/// teardown at exit (0.34 s on a one-H200 host: `-level 6` 0.415 s on the GPU, 0.078 s on the CPU).
constexpr double kGpuStartSeconds = 0.35;

/// What a run asks of the labeller.
struct LabelWork {
  int level = 0;
  std::uint64_t sites = 0;       ///< 0: not read yet (the estimate then takes one: the least work)
  std::uint64_t candidates = 0;  ///< points, arcs and fixed cells the tree is built from
  bool outlines = true;          ///< the outline cells (vector output's label_outlines); false: a raster
  double share = 1;              ///< of the level's codes the outlines are found for (a tile job's range)
  std::uint64_t every_cell = 0;  ///< cells labelled one by one besides: the cells layer's, a raster's pixels
  int threads = 1;               ///< CPU threads
};

/// The choice, and why.
struct AutoDevice {
  bool gpu = false;
  double work_cells = 0;   ///< the work, in cells (kCpuSecondsPerCell each on one thread)
  double start_cells = 0;  ///< kGpuStartSeconds in the same cells, on the run's threads
  int threads = 1;
  /// "2.2 M cells of work, below the GPU's start (4.7 M on 2 threads)".
  std::string reason() const;
};

/// The work of `work` and the GPU's start in cells; the GPU when the work is the larger. Pure.
AutoDevice choose_auto_device(const LabelWork& work);

/// Outline cells of a level with `sites` spread evenly (0 counts as 1): the row ends, and the
/// boundary cells along the Voronoi edges, whose length grows as the square root of the sites
/// (about 6.6 sqrt(n) radians for n sites), about 3 boundary cells per cell edge
/// (pi / 2^(level+1) radians) of it; at most every cell.
double expected_outline_cells(int level, std::uint64_t sites);

}  // namespace qtmv::label
