#include "measure/edge_solver.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure {

namespace {

constexpr int kRecentBits = 14;  // 16384 slots of 56 bytes (917 KB): a thread's second-level cache

std::uint64_t bits_of(double x) {  // exact bits: -0 and +0 differ
  std::uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

}  // namespace

struct EdgeSolver::Recent::Slot {
  std::uint64_t key[4];  // the canonical problem: lat1, lat2, lon12, lon12s
  CanonicalSolution solution;
  bool filled = false;
};

EdgeSolver::Recent::Recent() : slots_(new Slot[std::size_t{1} << kRecentBits]) {}

EdgeSolver::Recent::~Recent() = default;

/// An edge's canonical problem, and where its solution is kept.
struct EdgeSolver::Recent::Keyed {
  CanonicalProblem problem;
  std::uint64_t key[4];  // the problem's bits: lat1, lat2, lon12, lon12s
  std::size_t slot;
};

EdgeSolver::Recent::Keyed EdgeSolver::Recent::keyed(const EdgeEnds& edge) {
  Keyed k;
  k.problem = canonical_problem(edge.from.lat, edge.from.lon, edge.to.lat, edge.to.lon);
  k.key[0] = bits_of(k.problem.lat1);
  k.key[1] = bits_of(k.problem.lat2);
  k.key[2] = bits_of(k.problem.lon12);
  k.key[3] = bits_of(k.problem.lon12s);
  std::uint64_t h = 0;
  for (const std::uint64_t word : k.key) h = (h ^ word) * 0x9E3779B97F4A7C15ull;
  k.slot = static_cast<std::size_t>((h ^ (h >> 29)) >> (64 - kRecentBits));
  return k;
}

EdgeUnits EdgeSolver::Recent::units(const Ellipsoid& ellipsoid, const Keyed& k) {
  Slot& slot = slots_[k.slot];
  if (!slot.filled || std::memcmp(slot.key, k.key, sizeof k.key) != 0) {
    std::memcpy(slot.key, k.key, sizeof k.key);
    slot.solution = solve_canonical(ellipsoid, k.problem);
    slot.filled = true;
  }
  return edge_units_of(signed_solution(k.problem, slot.solution));
}

EdgeUnits EdgeSolver::Recent::units(const Ellipsoid& ellipsoid, const EdgeEnds& edge) {
  return units(ellipsoid, keyed(edge));
}

void EdgeSolver::Recent::units(const Ellipsoid& ellipsoid, const EdgeEnds* edges, std::size_t count, EdgeUnits* out) {
  // A chunk's slots fetched first: a slot is mostly a cache miss, and the misses then overlap.
  constexpr std::size_t kChunk = 16;
  Keyed chunk[kChunk];
  for (std::size_t first = 0; first < count; first += kChunk) {
    const std::size_t n = std::min(kChunk, count - first);
    for (std::size_t j = 0; j < n; ++j) {
      chunk[j] = keyed(edges[first + j]);
      __builtin_prefetch(&slots_[chunk[j].slot]);
    }
    for (std::size_t j = 0; j < n; ++j) out[first + j] = units(ellipsoid, chunk[j]);
  }
}

EdgeSolver::EdgeSolver(int cuda_device, std::string* problem) : ellipsoid_(wgs84_ellipsoid()) {
  if (cuda_device < 0) return;
  try {
    lanes_ = std::make_unique<cuda::EdgeLanes>(cuda_device, ellipsoid_, kBatchEdges);
  } catch (const std::runtime_error& e) {
    if (problem) *problem = e.what();
  }
}

EdgeSolver::~EdgeSolver() = default;

void EdgeSolver::solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out, Recent* recent) const {
  if (lanes_) {
    lanes_->solve(edges, count, out);
    return;
  }
  std::unique_ptr<Recent> own;
  if (!recent) {
    own = std::make_unique<Recent>();
    recent = own.get();
  }
  recent->units(ellipsoid_, edges, count, out);
}

}  // namespace qtmv::measure
