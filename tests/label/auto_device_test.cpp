// -device auto's estimate (label/auto_device.hpp): the CPU for work below a GPU's start, the GPU
// beyond, for the cases of bench/RESULTS.md and issue 37; the choice moves the right way with
// each input; the summary's reason.
#include <gtest/gtest.h>

#include <string>

#include "grid/qtm.hpp"
#include "label/auto_device.hpp"

namespace qtmv::label {
namespace {

constexpr std::uint64_t kCentres = 241;  // testdata/country_centres.csv

LabelWork points(int level, std::uint64_t sites, int threads) {
  LabelWork w;
  w.level = level;
  w.sites = sites;
  w.candidates = sites;
  w.threads = threads;
  return w;
}

TEST(AutoDevice, SmallRunsStayOnTheCpu) {
  // Issue 37: country centres at level 10 took 0.54 s on the GPU that auto picked, 0.11 s on the CPU.
  EXPECT_FALSE(choose_auto_device(points(10, kCentres, 16)).gpu);
  EXPECT_FALSE(choose_auto_device(points(10, kCentres, 2)).gpu);
  // Centres L13 regions: 0.33 s on 16 CPU threads against 0.53 s on one H200 (bench/RESULTS.md).
  EXPECT_FALSE(choose_auto_device(points(13, kCentres, 16)).gpu);
  EXPECT_FALSE(choose_auto_device(points(6, kCentres, 16)).gpu);  // -level 6: almost no work
}

TEST(AutoDevice, LargeRunsTakeTheGpu) {
  EXPECT_TRUE(choose_auto_device(points(16, kCentres, 16)).gpu);
  // 135 233 points L13: 5.07 s on a GPU, 8.77 s on 64 CPU threads.
  EXPECT_TRUE(choose_auto_device(points(13, 135233, 64)).gpu);
  EXPECT_TRUE(choose_auto_device(points(14, 1000000, 64)).gpu);
  EXPECT_TRUE(choose_auto_device(points(12, 1000000, 16)).gpu);
  // Every cell of the cells layer, every pixel of a raster (0.025 degrees: 104 M pixels).
  LabelWork cells = points(12, kCentres, 16);
  EXPECT_FALSE(choose_auto_device(cells).gpu);
  cells.every_cell = grid::cell_count(12);
  EXPECT_TRUE(choose_auto_device(cells).gpu);
  LabelWork raster = points(12, kCentres, 16);
  raster.outlines = false;
  raster.every_cell = 14400ull * 7200ull;
  EXPECT_TRUE(choose_auto_device(raster).gpu);
}

TEST(AutoDevice, TheChoiceFollowsTheWorkAndTheThreads) {
  // The GPU's start in cells grows with the CPU's threads, up to kCpuScalingThreads.
  const AutoDevice two = choose_auto_device(points(12, 10000, 2));
  const AutoDevice sixteen = choose_auto_device(points(12, 10000, 16));
  const AutoDevice many = choose_auto_device(points(12, 10000, 64));
  EXPECT_DOUBLE_EQ(two.start_cells, kGpuStartSeconds * 2 / kCpuSecondsPerCell);
  EXPECT_DOUBLE_EQ(sixteen.start_cells, 8 * two.start_cells);
  EXPECT_DOUBLE_EQ(many.start_cells, sixteen.start_cells);
  EXPECT_EQ(many.threads, 64);
  EXPECT_DOUBLE_EQ(two.work_cells, many.work_cells);
  // More sites, a finer level, a larger share: never less work.
  for (int level = 4; level <= 20; ++level) {
    double last = 0;
    for (std::uint64_t sites : {0ull, 1ull, 100ull, 10000ull, 1000000ull}) {
      const double work = choose_auto_device(points(level, sites, 16)).work_cells;
      EXPECT_GE(work, last) << level << " " << sites;
      last = work;
    }
    EXPECT_LE(choose_auto_device(points(level, 1000, 16)).work_cells,
              choose_auto_device(points(level + 1, 1000, 16)).work_cells);
  }
  LabelWork tile = points(16, kCentres, 16);
  tile.share = 0.125;
  EXPECT_LT(choose_auto_device(tile).work_cells, choose_auto_device(points(16, kCentres, 16)).work_cells);
  // Before the read (no sites) the work is the least the plan can take.
  EXPECT_LE(choose_auto_device(points(14, 0, 16)).work_cells, choose_auto_device(points(14, kCentres, 16)).work_cells);
  // The outline pass never counts more than every cell of the level once.
  LabelWork dense = points(8, 1000000, 16);
  dense.candidates = 0;
  EXPECT_DOUBLE_EQ(choose_auto_device(dense).work_cells, static_cast<double>(grid::cell_count(8)));
}

TEST(AutoDevice, TheReasonSaysTheWorkAndTheStart) {
  LabelWork w;
  w.level = 10;
  w.outlines = false;
  w.every_cell = 8400000;
  w.threads = 4;
  const AutoDevice cpu = choose_auto_device(w);
  EXPECT_FALSE(cpu.gpu);
  EXPECT_EQ(cpu.reason(), "8.4 M cells of work, below the GPU's start (9.3 M on 4 threads)");
  w.threads = 1;
  const AutoDevice gpu = choose_auto_device(w);
  EXPECT_TRUE(gpu.gpu);
  EXPECT_EQ(gpu.reason(), "8.4 M cells of work, above the GPU's start (2.3 M on 1 thread)");
}

TEST(AutoDevice, OutlineCellsFollowTheSitesAndTheLevel) {
  // The row ends alone for one site at level 0 and 1: 8 octants' rows, 2 ends each but the pole's.
  EXPECT_GE(expected_outline_cells(10, 0), 8.0 * (2 * 1024 - 1));
  EXPECT_DOUBLE_EQ(expected_outline_cells(10, 0), expected_outline_cells(10, 1));
  // The boundary grows as the square root of the sites, and 2x per level.
  const double rows = 8.0 * (2 * 4096 - 1);
  EXPECT_NEAR((expected_outline_cells(12, 40000) - rows) / (expected_outline_cells(12, 10000) - rows), 2.0, 1e-9);
  EXPECT_LE(expected_outline_cells(3, 1000000), 8.0 * (2 * 8 - 1) + static_cast<double>(grid::cell_count(3)));
}

}  // namespace
}  // namespace qtmv::label
