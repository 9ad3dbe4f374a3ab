// EdgeSolver's CUDA back end: the deterministic geodesic of measure/geodesic_math.hpp, compiled
// without FMA contraction (qtmv::grid adds --fmad=false), one edge a thread, so that a batch's
// measures equal the CPU's bit for bit. This file only launches; its memory is RAII
// (device_memory.cuh: DeviceArray, PinnedBuffer).
#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <condition_variable>
#include <cstring>
#include <mutex>

#include "device_memory.cuh"
#include "measure/edge_solver_cuda.hpp"

namespace qtmv::measure::cuda {

namespace {

using device_memory::DeviceArray;
using device_memory::FaultStep;
using device_memory::PinnedBuffer;

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
  PinnedBuffer host_edges;  ///< EdgeEnds
  PinnedBuffer host_units;  ///< EdgeUnits
  DeviceArray<EdgeEnds> device_edges;
  DeviceArray<EdgeUnits> device_units;
  bool busy = false;
};

}  // namespace

struct EdgeLanes::State {
  int device = 0;
  Ellipsoid ellipsoid;
  std::size_t capacity = 0;
  std::array<Lane, kLanes> lanes;
  std::mutex lock;
  std::condition_variable freed;

  ~State() {
    // Teardown: errors are not reported (an earlier one was). The buffers free themselves
    // after this, on this device.
    (void)cudaSetDevice(device);
    for (Lane& lane : lanes) {
      if (!lane.stream) continue;
      (void)cudaStreamSynchronize(lane.stream);
      (void)cudaStreamDestroy(lane.stream);
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
  for (Lane& lane : s.lanes) {
    QTMV_CUDA_CHECK(cudaStreamCreateWithFlags(&lane.stream, cudaStreamNonBlocking));
    lane.host_edges.get(capacity * sizeof(EdgeEnds));
    lane.host_units.get(capacity * sizeof(EdgeUnits));
    lane.device_edges = DeviceArray<EdgeEnds>::plain(capacity, FaultStep::none);
    lane.device_units = DeviceArray<EdgeUnits>::plain(capacity, FaultStep::none);
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
      // The lane's page-locked buffers, of `capacity` edges since the constructor.
      void* host_edges = lane.host_edges.get(n * sizeof(EdgeEnds));
      void* host_units = lane.host_units.get(n * sizeof(EdgeUnits));
      std::memcpy(host_edges, edges + first, n * sizeof(EdgeEnds));
      QTMV_CUDA_CHECK(cudaMemcpyAsync(lane.device_edges.get(), host_edges, n * sizeof(EdgeEnds), cudaMemcpyHostToDevice,
                                      lane.stream));
      const auto blocks = static_cast<unsigned>((n + kBlock - 1) / kBlock);
      solve_edges<<<blocks, kBlock, 0, lane.stream>>>(s.ellipsoid, lane.device_edges.get(), n,
                                                      lane.device_units.get());
      QTMV_CUDA_CHECK(cudaGetLastError());
      QTMV_CUDA_CHECK(cudaMemcpyAsync(host_units, lane.device_units.get(), n * sizeof(EdgeUnits),
                                      cudaMemcpyDeviceToHost, lane.stream));
      QTMV_CUDA_CHECK(cudaStreamSynchronize(lane.stream));
      std::memcpy(out + first, host_units, n * sizeof(EdgeUnits));
    } catch (...) {
      s.give_back(lane);
      throw;
    }
    s.give_back(lane);
  }
}

}  // namespace qtmv::measure::cuda
