// EdgeSolver's CUDA back end: the deterministic geodesic of measure/geodesic_math.hpp, compiled
// without FMA contraction (qtmv::grid adds --fmad=false), one edge a thread, so that a batch's
// measures equal the CPU's bit for bit. This file only launches and manages memory.
#include <cuda_runtime.h>

#include <condition_variable>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "cuda_error.hpp"
#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure::cuda {

namespace {

/// Throws std::runtime_error naming the failed call and its place in the source.
void check(cudaError_t status, const char* call, const char* file, int line) {
  if (status == cudaSuccess) return;
  throw std::runtime_error(cuda_error::describe(status, call, file, line));
}
#define QTMV_CUDA_CHECK(call) check((call), #call, __FILE__, __LINE__)

/// Streams, so that one host thread's copies overlap another's kernel.
constexpr int kLanes = 4;
constexpr int kBlock = 128;

__global__ void solve_edges(Ellipsoid ellipsoid, const EdgeEnds* edges, std::size_t count, EdgeUnits* out) {
  const std::size_t k = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) out[k] = edge_units(ellipsoid, edges[k]);
}

/// One stream with its buffers: page-locked on the host (copies at the bus's speed), and on the
/// device.
struct Lane {
  cudaStream_t stream = nullptr;
  EdgeEnds* host_edges = nullptr;
  EdgeUnits* host_units = nullptr;
  EdgeEnds* device_edges = nullptr;
  EdgeUnits* device_units = nullptr;
  bool busy = false;
};

}  // namespace

struct EdgeLanes::State {
  int device = 0;
  Ellipsoid ellipsoid;
  std::size_t capacity = 0;
  std::vector<Lane> lanes;
  std::mutex lock;
  std::condition_variable freed;

  ~State() {
    // Teardown: errors are not reported (an earlier one was).
    (void)cudaSetDevice(device);
    for (Lane& lane : lanes) {
      if (lane.stream) (void)cudaStreamSynchronize(lane.stream);
      (void)cudaFreeHost(lane.host_edges);
      (void)cudaFreeHost(lane.host_units);
      (void)cudaFree(lane.device_edges);
      (void)cudaFree(lane.device_units);
      if (lane.stream) (void)cudaStreamDestroy(lane.stream);
    }
  }

  Lane& take() {
    std::unique_lock<std::mutex> hold(lock);
    for (;;) {
      for (Lane& lane : lanes) {
        if (!lane.busy) {
          lane.busy = true;
          return lane;
        }
      }
      freed.wait(hold);
    }
  }

  void give_back(Lane& lane) {
    {
      const std::lock_guard<std::mutex> hold(lock);
      lane.busy = false;
    }
    freed.notify_one();
  }
};

EdgeLanes::EdgeLanes(int device, const Ellipsoid& ellipsoid, std::size_t capacity)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.device = device;
  s.ellipsoid = ellipsoid;
  s.capacity = capacity;
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  s.lanes.resize(kLanes);
  for (Lane& lane : s.lanes) {
    QTMV_CUDA_CHECK(cudaStreamCreateWithFlags(&lane.stream, cudaStreamNonBlocking));
    QTMV_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&lane.host_edges), capacity * sizeof(EdgeEnds)));
    QTMV_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&lane.host_units), capacity * sizeof(EdgeUnits)));
    QTMV_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&lane.device_edges), capacity * sizeof(EdgeEnds)));
    QTMV_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&lane.device_units), capacity * sizeof(EdgeUnits)));
  }
}

EdgeLanes::~EdgeLanes() = default;

void EdgeLanes::solve(const EdgeEnds* edges, std::size_t count, EdgeUnits* out) {
  State& s = *state_;
  QTMV_CUDA_CHECK(cudaSetDevice(s.device));  // this thread's current device
  for (std::size_t first = 0; first < count; first += s.capacity) {
    const std::size_t n = std::min(s.capacity, count - first);
    Lane& lane = s.take();
    try {
      std::memcpy(lane.host_edges, edges + first, n * sizeof(EdgeEnds));
      QTMV_CUDA_CHECK(
          cudaMemcpyAsync(lane.device_edges, lane.host_edges, n * sizeof(EdgeEnds), cudaMemcpyHostToDevice, lane.stream));
      const auto blocks = static_cast<unsigned>((n + kBlock - 1) / kBlock);
      solve_edges<<<blocks, kBlock, 0, lane.stream>>>(s.ellipsoid, lane.device_edges, n, lane.device_units);
      QTMV_CUDA_CHECK(cudaGetLastError());
      QTMV_CUDA_CHECK(
          cudaMemcpyAsync(lane.host_units, lane.device_units, n * sizeof(EdgeUnits), cudaMemcpyDeviceToHost, lane.stream));
      QTMV_CUDA_CHECK(cudaStreamSynchronize(lane.stream));
      std::memcpy(out + first, lane.host_units, n * sizeof(EdgeUnits));
    } catch (...) {
      s.give_back(lane);
      throw;
    }
    s.give_back(lane);
  }
}

}  // namespace qtmv::measure::cuda
