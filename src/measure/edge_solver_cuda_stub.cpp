// A build without CUDA: EdgeLanes cannot be made (EdgeSolver then stays on the CPU only when
// asked for it; asking for a device is an error, as the labeller's stub reports).
#include <stdexcept>

#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure::cuda {

struct EdgeLanes::State {};

EdgeLanes::EdgeLanes(int, const Ellipsoid&, std::size_t) {
  throw std::runtime_error("qtmvoronoi was built without CUDA");
}

EdgeLanes::~EdgeLanes() = default;

void EdgeLanes::solve(const EdgeEnds*, std::size_t, EdgeUnits*) {
  throw std::runtime_error("qtmvoronoi was built without CUDA");
}

}  // namespace qtmv::measure::cuda
