// The writer's geodesics alone: cell edges of random cells solved by measure::EdgeSolver on all
// CPU cores (in batches, as the regions' pass does) and on a CUDA device, with their bits
// compared. Core-only (no GDAL), so that it runs on the GPU machine.
//
//   edge_bench [--level L] [--edges N] [--repeat R] [--device cpu|cuda|both]
//
// Prints one line per device: edges, the median wall time of R runs (seconds), edges per second;
// exits 1 when the CPU's and the device's measures differ.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "grid/qtm.hpp"
#include "measure/edge_solver.hpp"

namespace {

using qtmv::measure::EdgeEnds;
using qtmv::measure::EdgeSolver;
using qtmv::measure::EdgeUnits;

struct Args {
  int level = 13;
  std::size_t edges = std::size_t{1} << 24;
  int repeat = 3;
  std::string device = "both";
};

[[noreturn]] void usage(const std::string& problem) {
  std::fprintf(stderr, "edge_bench: %s\nusage: edge_bench [--level L] [--edges N] [--repeat R] [--device cpu|cuda|both]\n",
               problem.c_str());
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int k = 1; k < argc; ++k) {
    const std::string opt = argv[k];
    if (k + 1 >= argc) usage(opt + " needs a value");
    const std::string value = argv[++k];
    if (opt == "--level") {
      a.level = std::atoi(value.c_str());
    } else if (opt == "--edges") {
      a.edges = static_cast<std::size_t>(std::atof(value.c_str()));
    } else if (opt == "--repeat") {
      a.repeat = std::max(1, std::atoi(value.c_str()));
    } else if (opt == "--device") {
      a.device = value;
      if (value != "cpu" && value != "cuda" && value != "both") usage("--device is cpu, cuda or both");
    } else {
      usage("unknown option " + opt);
    }
  }
  if (a.level < 0 || a.level > qtmv::grid::kMaxLevel) usage("--level out of range");
  return a;
}

/// The edges of random cells of the level (runs of a cell's edges, as an outline's are).
std::vector<EdgeEnds> random_cell_edges(int level, std::size_t count) {
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<qtmv::grid::Code> code(0, qtmv::grid::cell_count(level) - 1);
  std::vector<EdgeEnds> edges;
  edges.reserve(count + qtmv::grid::kMaxPolygonCorners);
  while (edges.size() < count) {
    qtmv::grid::LonLat ring[qtmv::grid::kMaxPolygonCorners];
    const int corners = qtmv::grid::cell_polygon(qtmv::grid::cell_of(code(rng), level), level, ring);
    for (int k = 0; k < corners; ++k) edges.push_back({ring[k], ring[(k + 1) % corners]});
  }
  edges.resize(count);
  return edges;
}

/// Median wall time (seconds) of `repeat` solves of all edges in batches on all threads.
double time_solver(const EdgeSolver& solver, const std::vector<EdgeEnds>& edges, std::vector<EdgeUnits>& out,
                   int repeat) {
  std::vector<double> times;
  const auto batches = static_cast<std::int64_t>((edges.size() + EdgeSolver::kBatchEdges - 1) / EdgeSolver::kBatchEdges);
  for (int r = 0; r < repeat; ++r) {
    const auto start = std::chrono::steady_clock::now();
#pragma omp parallel for schedule(dynamic, 1)
    for (std::int64_t b = 0; b < batches; ++b) {
      const std::size_t first = static_cast<std::size_t>(b) * EdgeSolver::kBatchEdges;
      solver.solve(edges.data() + first, std::min(EdgeSolver::kBatchEdges, edges.size() - first), out.data() + first);
    }
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  const std::vector<EdgeEnds> edges = random_cell_edges(a.level, a.edges);
  std::vector<EdgeUnits> cpu(edges.size()), gpu(edges.size());
  std::printf("device,level,edges,median_s,edges_per_s\n");
  const auto report = [&](const char* name, double seconds) {
    std::printf("%s,%d,%zu,%.4f,%.4g\n", name, a.level, edges.size(), seconds, static_cast<double>(edges.size()) / seconds);
  };
  if (a.device != "cuda") report("cpu", time_solver(EdgeSolver(-1), edges, cpu, a.repeat));
  if (a.device != "cpu") {
    const EdgeSolver device(0);
    time_solver(device, edges, gpu, 1);  // the first run pays the kernel's load
    report("cuda", time_solver(device, edges, gpu, a.repeat));
  }
  if (a.device == "both") {
    std::size_t differ = 0;
    for (std::size_t k = 0; k < edges.size(); ++k) differ += std::memcmp(&cpu[k], &gpu[k], sizeof(EdgeUnits)) != 0;
    std::printf("# CPU and CUDA measures differ for %zu of %zu edges\n", differ, edges.size());
    return differ == 0 ? 0 : 1;
  }
  return 0;
}
