// The run's plan: the CUDA devices are counted while the sites are read (label::DeviceStartup),
// so the plan leaves what they decide to settle_devices: the check of -device against the count,
// the labeller's tiles, the label stage's slice of the progress.
#include <gtest/gtest.h>

#include <gdal_priv.h>

#include <string>
#include <tuple>
#include <vector>

#include "../test_temp_dir.hpp"
#include "label/device_startup.hpp"
#include "label/labeller.hpp"
#include "pipeline/run_plan.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {
namespace {

constexpr std::uint64_t kCpuTileBytes = std::uint64_t{64} << 20;  // run_plan.cpp's

VoronoiOptions options_for(const std::string& device) {
  VoronoiOptions o;
  o.level = 8;
  o.device = device;
  o.check_disk_space = false;
  return o;
}

RunPlan planned(const VoronoiOptions& o) {
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  return plan_run(test::process_temp_dir() + "/plan.gpkg", o);
}

std::string device_error(const RunPlan& plan, int cuda_devices) {
  try {
    check_devices(plan, cuda_devices);
  } catch (const VoronoiError& e) {
    return e.what();
  }
  return "";
}

TEST(RunPlan, DevicesAreCheckedAgainstTheCount) {
  // Planning counts nothing: a GPU asked for is checked once the count is in.
  const RunPlan one = planned(options_for("cuda:1"));
  EXPECT_EQ(one.cuda_devices, -1);
  EXPECT_EQ(device_error(one, 0), "-device cuda:1: no usable CUDA GPU found; use -device cpu or auto");
  EXPECT_EQ(device_error(one, 1), "-device cuda:1: this host has 1 CUDA device(s); use -device cpu or auto");
  EXPECT_EQ(device_error(one, 2), "");
  const RunPlan all = planned(options_for("cuda:all"));
  EXPECT_EQ(device_error(all, 0), "-device cuda:all: no usable CUDA GPU found; use -device cpu or auto");
  EXPECT_EQ(device_error(all, 1), "");
  for (const char* device : {"cpu", "auto"}) EXPECT_EQ(device_error(planned(options_for(device)), 0), "") << device;

  RunPlan settled = one;
  EXPECT_THROW(settle_devices(settled, options_for("cuda:1"), 1), VoronoiError);
  settle_devices(settled, options_for("cuda:1"), 2);
  EXPECT_EQ(settled.cuda_devices, 2);
}

TEST(RunPlan, TilesAndProgressFollowTheSettledDevice) {
  const VoronoiOptions o = options_for("auto");
  const RunPlan before = planned(o);
  // Before the count "auto" plans the CPU's tiles (the lenient memory check).
  EXPECT_EQ(before.label.memory_limit_bytes, kCpuTileBytes);
  EXPECT_DOUBLE_EQ(before.read_end, 0.05);

  RunPlan cpu = before, gpu = before;
  settle_devices(cpu, o, 0);
  settle_devices(gpu, o, 1);
  EXPECT_EQ(cpu.label.memory_limit_bytes, kCpuTileBytes);
  EXPECT_EQ(gpu.label.memory_limit_bytes, 0u);  // the labeller's own: a quarter of RAM
  // Labelling is a larger share of a CPU run than of a GPU run.
  EXPECT_GT(cpu.label_end, gpu.label_end);
  EXPECT_GT(gpu.label_end, gpu.read_end);
  EXPECT_LT(cpu.label_end, 1.0);

  // -memory is kept whatever the device.
  VoronoiOptions limited = o;
  limited.memory_limit_bytes = std::uint64_t{3} << 30;
  RunPlan asked = planned(limited);
  EXPECT_EQ(asked.label.memory_limit_bytes, limited.memory_limit_bytes);
  settle_devices(asked, limited, 1);
  EXPECT_EQ(asked.label.memory_limit_bytes, limited.memory_limit_bytes);
}

// -device auto's estimate takes what the plan writes: the outlines, the cells layer's every cell,
// a raster's pixels, a tile's share; once the sites are read it settles the device.
TEST(RunPlan, AutoEstimatesWhatThePlanWrites) {
  VoronoiOptions o = options_for("auto");
  o.level = 12;
  o.threads = 16;
  const RunPlan regions = planned(o);
  const label::AutoDevice before = estimate_auto_device(regions, 0, 0);
  const label::AutoDevice after = estimate_auto_device(regions, 241, 241);
  EXPECT_FALSE(after.gpu);  // the country centres at level 12: the CPU's
  EXPECT_LE(before.work_cells, after.work_cells);
  EXPECT_EQ(after.threads, 16);

  VoronoiOptions with_cells = o;
  with_cells.vector.layers = {"regions", "cells"};
  const label::AutoDevice cells = estimate_auto_device(planned(with_cells), 241, 241);
  EXPECT_DOUBLE_EQ(cells.work_cells - after.work_cells, static_cast<double>(grid::cell_count(12)));
  EXPECT_TRUE(cells.gpu);

  VoronoiOptions tile = o;
  tile.tile_index = 1;
  tile.tile_count = 8;
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  const RunPlan tile_plan = plan_tile_job(test::process_temp_dir() + "/plan.qtmt", tile);
  EXPECT_LT(estimate_auto_device(tile_plan, 241, 241).work_cells, after.work_cells);

  RunPlan settled = regions;
  label::AutoDevice gpu = after;
  gpu.gpu = true;
  settle_auto_device(settled, gpu, 0);
  EXPECT_EQ(settled.label.device, "cpu");  // no GPU to take
  EXPECT_EQ(auto_device_summary("cpu (16 threads)", gpu, 0).find("auto: cpu (16 threads), "), 0u);
  EXPECT_NE(auto_device_summary("cpu (16 threads)", gpu, 0).find(", but no usable CUDA GPU"), std::string::npos);
  settle_auto_device(settled, gpu, 2);
  EXPECT_EQ(settled.label.device, "cuda");
  settle_auto_device(settled, after, 2);
  EXPECT_EQ(settled.label.device, "cpu");
  EXPECT_EQ(auto_device_summary("cpu (16 threads)", after, 2), "auto: cpu (16 threads), " + after.reason());
}

std::string plan_error(const std::string& destination, const VoronoiOptions& o) {
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  try {
    if (o.tile_count > 0) {
      plan_tile_job(destination, o);
    } else {
      plan_run(destination, o);
    }
  } catch (const VoronoiError& e) {
    return e.what();
  }
  return "";
}

TEST(RunPlan, BandsAreHonouredOrRefusedInEveryMode) {
  const std::string dir = test::process_temp_dir();
  VoronoiOptions o = options_for("cpu");
  // A raster: only the labels its bands need.
  for (const auto& [bands, distance, boundary] :
       std::vector<std::tuple<std::vector<write::RasterBand>, bool, bool>>{
           {{}, true, true},
           {{write::RasterBand::fid}, false, false},
           {{write::RasterBand::boundary, write::RasterBand::fid}, false, true},
           {{write::RasterBand::distance}, true, false}}) {
    o.raster.bands = bands;
    const RunPlan plan = plan_run(dir + "/plan.tif", o);
    EXPECT_EQ(plan.label.want_distance, distance);
    EXPECT_EQ(plan.label.want_boundary, boundary);
  }
  o.raster.bands = {write::RasterBand::fid, write::RasterBand::fid};
  EXPECT_EQ(plan_error(dir + "/plan.tif", o), "-bands: band 'fid' named twice");
  // Vector output, a merge's, and a tile job's product hold no bands.
  o.raster.bands = {write::RasterBand::fid};
  EXPECT_EQ(plan_error(dir + "/plan.gpkg", o), "-bands is for raster output; GPKG output is vector: use -layers");
  o.merge = {dir};
  EXPECT_EQ(plan_error(dir + "/plan.gpkg", o), "-bands is for raster output; GPKG output is vector: use -layers");
  EXPECT_NE(plan_error(dir + "/plan.tif", o).find("-merge joins tile products into vector output"), std::string::npos);
  o.merge.clear();
  o.tile_index = 1;
  o.tile_count = 4;
  EXPECT_EQ(plan_error(dir + "/t.qtmt", o),
            "-bands: a tile job writes a tile product, not a raster; a raster is written by a whole run, or in parts "
            "by tile jobs with -part");
}

TEST(DeviceStartup, CountsWhatTheLabellerCounts) {
  const int gpus = label::cuda_device_count();
  {
    label::DeviceStartup cpu("cpu", true);
    EXPECT_TRUE(cpu.counted());  // nothing to count
    EXPECT_EQ(cpu.device_count(), 0);
  }
  for (const bool contexts : {false, true}) {
    label::DeviceStartup devices("auto", contexts);
    EXPECT_EQ(devices.device_count(), gpus);
    EXPECT_TRUE(devices.counted());
    devices.wait();
  }
  // A name the plan refuses starts nothing and throws nothing.
  label::DeviceStartup bad("gpu", true);
  EXPECT_EQ(bad.device_count(), gpus);
  label::DeviceStartup missing("cuda:" + std::to_string(gpus), true);
  EXPECT_EQ(missing.device_count(), gpus);
}

}  // namespace
}  // namespace qtmv::pipeline
