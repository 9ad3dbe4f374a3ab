// EdgeSolver: the same bits on the CPU and on a CUDA device (the test needs a GPU; without one it
// is skipped), batches of any size, several threads at once.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "grid/qtm.hpp"
#include "label/label_cuda.hpp"
#include "measure/edge_solver.hpp"

namespace qtmv::measure {
namespace {

/// Every edge of every cell polygon of a level, both ways round.
std::vector<EdgeEnds> cell_edges(int level) {
  std::vector<EdgeEnds> edges;
  for (grid::Code code = 0; code < grid::cell_count(level); ++code) {
    grid::LonLat ring[grid::kMaxPolygonCorners];
    const int corners = grid::cell_polygon(grid::cell_of(code, level), level, ring);
    for (int k = 0; k < corners; ++k) {
      edges.push_back({ring[k], ring[(k + 1) % corners]});
      edges.push_back({ring[(k + 1) % corners], ring[k]});
    }
  }
  return edges;
}

/// The cell edges of levels 0-7, and of random cells of levels 8-20, and random lines of every
/// length (to near antipodes).
std::vector<EdgeEnds> test_edges() {
  std::vector<EdgeEnds> edges;
  for (int level = 0; level <= 7; ++level) {
    const std::vector<EdgeEnds> more = cell_edges(level);
    edges.insert(edges.end(), more.begin(), more.end());
  }
  std::mt19937_64 rng(42);
  for (int level = 8; level <= 20; ++level) {
    std::uniform_int_distribution<grid::Code> code(0, grid::cell_count(level) - 1);
    for (int n = 0; n < 5000; ++n) {
      grid::LonLat ring[grid::kMaxPolygonCorners];
      const int corners = grid::cell_polygon(grid::cell_of(code(rng), level), level, ring);
      for (int k = 0; k < corners; ++k) edges.push_back({ring[k], ring[(k + 1) % corners]});
    }
  }
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
  for (int n = 0; n < 20000; ++n) edges.push_back({{lon(rng), lat(rng)}, {lon(rng), lat(rng)}});
  return edges;
}

bool same_bits(const EdgeUnits& a, const EdgeUnits& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(EdgeSolver, CudaGivesTheCpusBits) {
  if (label::cuda::device_count() == 0) GTEST_SKIP() << "no CUDA device";
  const std::vector<EdgeEnds> edges = test_edges();
  ASSERT_GT(edges.size(), 2 * EdgeSolver::kBatchEdges);  // several of the device's pieces
  std::vector<EdgeUnits> cpu(edges.size()), gpu(edges.size());
  EdgeSolver(-1).solve(edges.data(), edges.size(), cpu.data());
  const EdgeSolver device(0);
  ASSERT_TRUE(device.on_device());
  device.solve(edges.data(), edges.size(), gpu.data());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (same_bits(cpu[k], gpu[k])) continue;
    if (++differ <= 5) {
      ADD_FAILURE() << "edge " << k << " (" << edges[k].from.lon << ", " << edges[k].from.lat << ") -> ("
                    << edges[k].to.lon << ", " << edges[k].to.lat << "): CPU area " << cpu[k].area << " length "
                    << cpu[k].length << ", CUDA area " << gpu[k].area << " length " << gpu[k].length;
    }
  }
  EXPECT_EQ(differ, 0u) << "of " << edges.size() << " edges";

  // Several threads' batches at once through the device's lanes: each gets its own answers.
  constexpr int kThreads = 8;
  std::vector<std::vector<EdgeUnits>> answers(kThreads, std::vector<EdgeUnits>(edges.size()));
  std::vector<std::thread> pool;
  for (int t = 0; t < kThreads; ++t) {
    pool.emplace_back([&, t] {
      const std::size_t first = static_cast<std::size_t>(t) * 977;  // each a different start
      for (std::size_t at = first; at < edges.size(); at += EdgeSolver::kBatchEdges / 3) {
        const std::size_t n = std::min<std::size_t>(EdgeSolver::kBatchEdges / 3, edges.size() - at);
        device.solve(edges.data() + at, n, answers[static_cast<std::size_t>(t)].data() + at);
      }
    });
  }
  for (std::thread& t : pool) t.join();
  for (int t = 0; t < kThreads; ++t) {
    const std::size_t first = static_cast<std::size_t>(t) * 977;
    for (std::size_t k = first; k < edges.size(); ++k) {
      ASSERT_TRUE(same_bits(answers[static_cast<std::size_t>(t)][k], cpu[k])) << "thread " << t << ", edge " << k;
    }
  }
}

TEST(EdgeSolver, EdgesBothWaysRoundCancel) {
  // The regions' sums rely on it: an edge between two sites is solved once, and counts for one
  // site with its S12 and for the other with -S12, as if solved the other way round.
  const EdgeSolver cpu(-1);
  for (int level = 0; level <= 6; ++level) {
    const std::vector<EdgeEnds> edges = cell_edges(level);  // pairs: (a, b), then (b, a)
    std::vector<EdgeUnits> units(edges.size());
    cpu.solve(edges.data(), edges.size(), units.data());
    for (std::size_t k = 0; k < edges.size(); k += 2) {
      ASSERT_LE(std::llabs(units[k].area + units[k + 1].area), 1) << "level " << level << ", edge " << k;
      ASSERT_LE(std::llabs(units[k].length - units[k + 1].length), 1) << "level " << level << ", edge " << k;
      const bool along_a_pole = std::fabs(edges[k].from.lat) == 90 && edges[k].to.lat == edges[k].from.lat;
      if (!along_a_pole) {
        ASSERT_GT(units[k].length, 0) << "level " << level << ", edge " << k;
      }
    }
  }
}

TEST(EdgeSolver, RecentSolutionsAreEachEdgesOwnBits) {
  // An edge whose canonical problem a thread solved before takes that solution: the bits of
  // solving it afresh. The cell edges of level 7 in code order, both ways round, then their
  // mirror images (latitudes negated, longitudes negated, shifted by 90 degrees), then random
  // lines, through one Recent from batch to batch (some slots taken by other problems meanwhile).
  std::vector<EdgeEnds> edges = cell_edges(7);
  const std::size_t cells = edges.size();
  for (std::size_t k = 0; k < cells; k += 7) {
    const EdgeEnds e = edges[k];  // a copy: the pushes move the vector
    edges.push_back({{e.from.lon, -e.from.lat}, {e.to.lon, -e.to.lat}});
    edges.push_back({{-e.from.lon, e.from.lat}, {-e.to.lon, e.to.lat}});
    const auto shifted = [](double lon) { return lon + 90 > 180 ? lon - 270 : lon + 90; };
    edges.push_back({{shifted(e.from.lon), e.from.lat}, {shifted(e.to.lon), e.to.lat}});
  }
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
  for (int n = 0; n < 20000; ++n) edges.push_back({{lon(rng), lat(rng)}, {lon(rng), lat(rng)}});
  edges.push_back({{0, 0}, {0, 0}});
  edges.push_back({{-0.0, 0}, {0, -0.0}});
  edges.push_back({{180, 0}, {-180, 0}});
  const EdgeSolver cpu(-1);
  EdgeSolver::Recent recent;
  const Ellipsoid wgs84 = wgs84_ellipsoid();
  std::vector<EdgeUnits> got(edges.size());
  for (std::size_t at = 0; at < edges.size(); at += EdgeSolver::kBatchEdges) {
    const std::size_t n = std::min(EdgeSolver::kBatchEdges, edges.size() - at);
    cpu.solve(edges.data() + at, n, got.data() + at, &recent);
  }
  for (std::size_t k = 0; k < edges.size(); ++k) {
    ASSERT_TRUE(same_bits(got[k], edge_units(wgs84, edges[k]))) << "edge " << k;
  }
  // In batches of any size (Recent takes them a chunk at a time), and one by one.
  EdgeSolver::Recent again;
  std::fill(got.begin(), got.end(), EdgeUnits{});
  for (std::size_t at = 0, n = 1; at < edges.size(); at += n, n = n % 41 + 1) {
    n = std::min(n, edges.size() - at);
    cpu.solve(edges.data() + at, n, got.data() + at, &again);
  }
  for (std::size_t k = 0; k < edges.size(); ++k) {
    ASSERT_TRUE(same_bits(got[k], edge_units(wgs84, edges[k]))) << "edge " << k;
    ASSERT_TRUE(same_bits(again.units(wgs84, edges[k]), got[k])) << "edge " << k;
  }
}

TEST(EdgeSolver, WithoutTheDeviceTheCpuSolves) {
  // A device that cannot be used (here: none, or an ordinal past the host's) leaves the work to
  // the CPU, with the reason, and the same answers.
  const int missing = label::cuda::device_count();
  std::string problem;
  const EdgeSolver solver(missing, &problem);
  EXPECT_FALSE(solver.on_device());
  EXPECT_FALSE(problem.empty());
  const std::vector<EdgeEnds> edges = cell_edges(3);
  std::vector<EdgeUnits> got(edges.size()), expected(edges.size());
  solver.solve(edges.data(), edges.size(), got.data());
  EdgeSolver(-1).solve(edges.data(), edges.size(), expected.data());
  for (std::size_t k = 0; k < edges.size(); ++k) ASSERT_TRUE(same_bits(got[k], expected[k])) << "edge " << k;
}

}  // namespace
}  // namespace qtmv::measure
