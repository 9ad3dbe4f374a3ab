#include "measure/edge_solver.hpp"

#include <stdexcept>

#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure {

EdgeSolver::EdgeSolver(int cuda_device, std::string* problem) : ellipsoid_(wgs84_ellipsoid()) {
  if (cuda_device < 0) return;
  try {
    lanes_ = std::make_unique<cuda::EdgeLanes>(cuda_device, ellipsoid_, kBatchEdges);
  } catch (const std::runtime_error& e) {
    if (problem) *problem = e.what();
  }
}

EdgeSolver::~EdgeSolver() = default;

void EdgeSolver::solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out) const {
  if (lanes_) {
    lanes_->solve(edges, count, out);
    return;
  }
  for (std::size_t k = 0; k < count; ++k) out[k] = edge_units(ellipsoid_, edges[k]);
}

}  // namespace qtmv::measure
