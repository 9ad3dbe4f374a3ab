#include "measure/edge_solver.hpp"

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

EdgeUnits EdgeSolver::Recent::units(const Ellipsoid& ellipsoid, const EdgeEnds& edge) {
  const CanonicalProblem problem = canonical_problem(edge.from.lat, edge.from.lon, edge.to.lat, edge.to.lon);
  const std::uint64_t key[4] = {bits_of(problem.lat1), bits_of(problem.lat2), bits_of(problem.lon12),
                                bits_of(problem.lon12s)};
  std::uint64_t h = 0;
  for (const std::uint64_t word : key) h = (h ^ word) * 0x9E3779B97F4A7C15ull;
  Slot& slot = slots_[(h ^ (h >> 29)) >> (64 - kRecentBits)];
  if (!slot.filled || std::memcmp(slot.key, key, sizeof key) != 0) {
    std::memcpy(slot.key, key, sizeof key);
    slot.solution = solve_canonical(ellipsoid, problem);
    slot.filled = true;
  }
  return edge_units_of(signed_solution(problem, slot.solution));
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
  for (std::size_t k = 0; k < count; ++k) out[k] = recent->units(ellipsoid_, edges[k]);
}

}  // namespace qtmv::measure
