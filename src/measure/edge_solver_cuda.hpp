// EdgeSolver's CUDA back end, as the host code sees it (the kernel is in cuda/edge_solver_cuda.cu).
// Without CUDA the build links edge_solver_cuda_stub.cpp, which throws on use.
#pragma once

#include <cstddef>
#include <memory>

#include "measure/edge_units.hpp"

namespace qtmv::measure::cuda {

/// A few streams of one device, each with its device and page-locked buffers for `capacity`
/// edges, so that several host threads' batches are copied and solved at once.
class EdgeLanes {
 public:
  /// Throws std::runtime_error when the device cannot be used.
  EdgeLanes(int device, const Ellipsoid& ellipsoid, std::size_t capacity);
  ~EdgeLanes();
  /// As EdgeSolver::solve: any count (in pieces of `capacity`), from any thread.
  void solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out);

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace qtmv::measure::cuda
