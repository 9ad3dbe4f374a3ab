// A run shows CUDA only the devices its -device names (common/visible_devices.hpp): on a GPU host
// the labels stay those of the CPU, the device used is the one the user named (by its PCI bus
// id, which no restriction renumbers), and every name stays the user's cuda:N. CUDA reads
// CUDA_VISIBLE_DEVICES once a process, so each case runs in a child process of this test:
//   --list            every device CUDA shows this process: "device N PCI" lines
//   --label DEVICE    restricts as qtmvoronoi does, labels on DEVICE and on the CPU, prints
//                     "name STATS_DEVICE", "same 0|1", "device NAME PCI" per device chosen
// Skipped without a GPU.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "common/visible_devices.hpp"
#include "label/label_cuda.hpp"
#include "label/label_engine.hpp"
#include "label/labeller.hpp"
#include "label/synthetic_sites.hpp"

namespace qtmv::label {
namespace {

int list_devices() {
  for (int d = 0; d < cuda::device_count(); ++d) std::cout << "device " << d << " " << cuda::device_info(d).pci_bus_id << "\n";
  return 0;
}

int label_on(const std::string& device) {
  restrict_visible_devices(device);
  SiteGeometry g;
  g.level = 8;
  std::mt19937_64 rng(37);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-80, 80);
  for (int k = 0; k < 300; ++k) add_point(g, lon(rng), lat(rng), k);
  try {
    LabelOptions options;
    options.device = device;
    Outlines on_device, on_cpu;
    const LabelStats stats = label_outlines(g.input(), options, &on_device);
    options.device = "cpu";
    label_outlines(g.input(), options, &on_cpu);
    const bool same = on_device.cells.size() == on_cpu.cells.size() &&
                      std::equal(on_device.cells.begin(), on_device.cells.end(), on_cpu.cells.begin(),
                                 [](const OutlineCell& a, const OutlineCell& b) {
                                   return a.code() == b.code() && a.site == b.site && a.boundary() == b.boundary();
                                 }) &&
                      on_device.cells_per_site == on_cpu.cells_per_site;
    std::cout << "name " << stats.device << "\nsame " << same << "\n";
    for (const DeviceChoice& d : choose_devices(device)) {
      if (d.cuda) std::cout << "device " << cuda_device_name(d.index) << " " << cuda::device_info(d.index).pci_bus_id << "\n";
    }
  } catch (const std::exception& e) {
    std::cout << "error " << e.what() << "\n";
  }
  return 0;
}

/// Runs this test's own binary with `args`, under `visible` as CUDA_VISIBLE_DEVICES (null: as
/// inherited); its standard output.
std::string child(const std::string& args, const char* visible = nullptr) {
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n <= 0) return "";
  self[n] = 0;
  const std::string command =
      (visible ? "env CUDA_VISIBLE_DEVICES='" + std::string(visible) + "' " : std::string()) + "'" + self + "' " + args;
  std::string out;
  if (FILE* pipe = popen(command.c_str(), "r")) {
    char buffer[4096];
    for (std::size_t got; (got = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) out.append(buffer, got);
    pclose(pipe);
  }
  return out;
}

/// The "device N PCI" lines' PCI ids, in order.
std::vector<std::string> pci_ids(const std::string& out) {
  std::vector<std::string> ids;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("device ", 0) == 0) ids.push_back(line.substr(line.rfind(' ') + 1));
  }
  return ids;
}

/// The host's devices as this process's environment shows them (this process starts no CUDA).
std::vector<std::string> host_devices() { return pci_ids(child("--list")); }

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(VisibleDevicesGpu, TheLastDeviceKeepsItsNameAndTheLabels) {
  const std::vector<std::string> all = host_devices();
  if (all.empty()) GTEST_SKIP() << "no CUDA GPU";
  const std::string last = "cuda:" + std::to_string(all.size() - 1);
  const std::string out = child("--label " + last);
  EXPECT_TRUE(contains(out, "name " + last + " (")) << out;
  EXPECT_TRUE(contains(out, "same 1")) << out;
  EXPECT_TRUE(contains(out, "device " + last + " " + all.back())) << out;
}

TEST(VisibleDevicesGpu, AListKeepsItsOrderAndNames) {
  const std::vector<std::string> all = host_devices();
  if (all.size() < 2) GTEST_SKIP() << "fewer than 2 CUDA GPUs";
  const std::string out = child("--label cuda:1,0");
  EXPECT_TRUE(contains(out, "name cuda:1 (")) << out;
  EXPECT_TRUE(contains(out, ", cuda:0 (")) << out;
  EXPECT_TRUE(contains(out, "same 1")) << out;
  EXPECT_EQ(pci_ids(out), (std::vector<std::string>{all[1], all[0]})) << out;
}

TEST(VisibleDevicesGpu, TheUsersOwnListIsComposed) {
  if (std::getenv("CUDA_VISIBLE_DEVICES")) GTEST_SKIP() << "CUDA_VISIBLE_DEVICES is set for the test itself";
  const std::vector<std::string> all = host_devices();
  if (all.size() < 2) GTEST_SKIP() << "fewer than 2 CUDA GPUs";
  // The user shows devices 1 and 0, in that order: their cuda:0 is the host's device 1.
  const std::string out = child("--label cuda:0", "1,0");
  EXPECT_TRUE(contains(out, "name cuda:0 (")) << out;
  EXPECT_TRUE(contains(out, "same 1")) << out;
  EXPECT_EQ(pci_ids(out), (std::vector<std::string>{all[1]})) << out;
}

TEST(VisibleDevicesGpu, AMissingDeviceIsNamed) {
  const std::vector<std::string> all = host_devices();
  if (all.empty()) GTEST_SKIP() << "no CUDA GPU";
  const std::string missing = "cuda:" + std::to_string(all.size());
  const std::string out = child("--label cuda:0," + std::to_string(all.size()));
  EXPECT_TRUE(contains(out, "error ")) << out;
  EXPECT_TRUE(contains(out, "no CUDA device " + missing)) << out;
}

}  // namespace
}  // namespace qtmv::label

int main(int argc, char** argv) {
  if (argc == 2 && std::string(argv[1]) == "--list") return qtmv::label::list_devices();
  if (argc == 3 && std::string(argv[1]) == "--label") return qtmv::label::label_on(argv[2]);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
