// The labeller's CUDA kernels and launches. The maths is the QTMV_HD code of src/label
// (label_math.hpp, label_tree.hpp), compiled here without FMA contraction (qtmv::grid adds
// --fmad=false), so the labels are those of the CPU path bit for bit.
#include <cuda_runtime.h>

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cuda_error.hpp"
#include "label/label_engine.hpp"
#include "label/label_cuda.hpp"
#include "label/label_tree.hpp"
#include "label/labeller.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label::cuda {

namespace {

/// Throws std::runtime_error naming the failed call and its place in the source; OutOfMemory
/// for a failed allocation (not sticky: the context stays usable).
void check(cudaError_t status, const char* call, const char* file, int line) {
  if (status == cudaSuccess) return;
  const std::string what = cuda_error::describe(status, call, file, line);
  if (status == cudaErrorMemoryAllocation) {
    (void)cudaGetLastError();  // or the next launch check would report it again
    throw OutOfMemory(what);
  }
  throw std::runtime_error(what);
}

/// Fault injection, for the tests: the environment variable QTMV_FAULT_CUDA_OOM names a step
/// that then fails as a device out of memory would (OutOfMemory, "injected by ..."):
///   build     the device tree build (the caller labels on the CPU instead);
///   reserve   reserve() of outputs for more than 65536 cells (the caller tries smaller tiles);
///   run       run() of any tile but the first (a failure mid-run: the rest goes to the CPU);
///   allocate  a device allocation's first try, while the memory pool holds idle memory (which
///             is then given back, and the allocation tried again).
/// The variable is read when a Labeller is made and again at each reserve() (the start of a run's
/// tiles; the tests set it between construction and reserve), not at every allocation and tile.
enum class FaultStep { none, build, reserve, run, allocate };

const char* fault_step_name(FaultStep step) {
  switch (step) {
    case FaultStep::build: return "build";
    case FaultStep::reserve: return "reserve";
    case FaultStep::run: return "run";
    case FaultStep::allocate: return "allocate";
    case FaultStep::none: break;
  }
  return "";
}

/// The step QTMV_FAULT_CUDA_OOM names (none when unset or naming no step).
FaultStep fault_step_from_environment() {
  const char* fault = std::getenv("QTMV_FAULT_CUDA_OOM");
  if (!fault) return FaultStep::none;
  for (const FaultStep step : {FaultStep::build, FaultStep::reserve, FaultStep::run, FaultStep::allocate}) {
    if (std::string(fault) == fault_step_name(step)) return step;
  }
  return FaultStep::none;
}

/// Throws OutOfMemory when `injected` (the fault QTMV_FAULT_CUDA_OOM names) is `step`.
void fail_if_injected(FaultStep injected, FaultStep step) {
  if (injected == step) {
    throw OutOfMemory(std::string("CUDA error cudaErrorMemoryAllocation (injected by QTMV_FAULT_CUDA_OOM=") +
                      fault_step_name(step) + ")");
  }
}
#define QTMV_CUDA_CHECK(call) check((call), #call, __FILE__, __LINE__)
/// After a kernel launch: launch errors now, execution errors at the next synchronisation.
#define QTMV_CUDA_CHECK_LAUNCH(name) check(cudaGetLastError(), "launch of " name, __FILE__, __LINE__)

// The tree build's scratch comes from the device's default memory pool, which keeps it mapped
// after the build (mapping GBs anew costs tens of milliseconds per build at level 15). That
// memory counts as free (pool_idle_bytes), and an allocation that fails gives it back to the
// system and tries once more (allocate).

/// Bytes the current device's default pool holds but does not use.
std::size_t pool_idle_bytes(int device) {
  cudaMemPool_t pool;
  if (cudaDeviceGetDefaultMemPool(&pool, device) != cudaSuccess) return 0;
  std::uint64_t reserved = 0, used = 0;
  if (cudaMemPoolGetAttribute(pool, cudaMemPoolAttrReservedMemCurrent, &reserved) != cudaSuccess ||
      cudaMemPoolGetAttribute(pool, cudaMemPoolAttrUsedMemCurrent, &used) != cudaSuccess) {
    return 0;
  }
  return reserved > used ? static_cast<std::size_t>(reserved - used) : 0;
}

/// Gives the current device's idle pool memory back to the system, once its work is done (a fault
/// of an earlier kernel surfaces here, as itself).
cudaError_t release_pool(int device) {
  cudaMemPool_t pool;
  cudaError_t status = cudaDeviceGetDefaultMemPool(&pool, device);
  if (status == cudaSuccess) status = cudaDeviceSynchronize();
  if (status == cudaSuccess) status = cudaMemPoolTrimTo(pool, 0);
  return status;
}

/// cudaMalloc, once more after the pool's idle memory went back to the system: the one way
/// plain device memory is allocated (DeviceArray::plain).
/// (injected FaultStep::allocate: the first try fails whenever the pool holds idle memory.)
cudaError_t allocate(void** pointer, std::size_t bytes, FaultStep injected_fault) {
  int device = 0;
  const cudaError_t current = cudaGetDevice(&device);
  if (current != cudaSuccess) return current;
  const bool injected = injected_fault == FaultStep::allocate && pool_idle_bytes(device) > 0;
  const cudaError_t status = injected ? cudaErrorMemoryAllocation : cudaMalloc(pointer, bytes);
  if (status != cudaErrorMemoryAllocation) return status;
  (void)cudaGetLastError();
  if (pool_idle_bytes(device) == 0) return status;
  const cudaError_t released = release_pool(device);
  return released == cudaSuccess ? cudaMalloc(pointer, bytes) : released;
}

// --- device memory ------------------------------------------------------------------------
//
// Every device array is a DeviceArray, allocated one of two ways, and freed the same way:
//  - plain: cudaMalloc through allocate() (out of memory: the pool's idle memory goes back to the
//    system and the allocation is tried once more). The arrays a Labeller keeps (candidates,
//    tree, outputs) and the constructors' scratch.
//  - pool: cudaMallocAsync from the device's default pool, on the default stream. The tree
//    build's scratch (Buffer), which grows level by level: the pool keeps that memory mapped for
//    the next build, where cudaMalloc and cudaFree would map and unmap it each time.

/// A device array of size() elements that frees itself as it was allocated. Move-only.
template <typename T>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  DeviceArray(DeviceArray&& other) noexcept : data_(other.data_), size_(other.size_), from_pool_(other.from_pool_) {
    other.data_ = nullptr;
    other.size_ = 0;
  }
  DeviceArray& operator=(DeviceArray&& other) noexcept {
    if (this != &other) {
      reset();
      data_ = other.data_;
      size_ = other.size_;
      from_pool_ = other.from_pool_;
      other.data_ = nullptr;
      other.size_ = 0;
    }
    return *this;
  }
  /// Destructors must not throw; errors here are left to the next call's check.
  ~DeviceArray() { reset(); }

  /// `count` elements by cudaMalloc (allocate(): `injected` FaultStep::allocate fails the first
  /// try); an empty array for count 0.
  static DeviceArray plain(std::size_t count, FaultStep injected) {
    DeviceArray array;
    if (count == 0) return array;
    T* p = nullptr;
    check(allocate(reinterpret_cast<void**>(&p), count * sizeof(T), injected), "cudaMalloc(&p, count * sizeof(T))",
          __FILE__, __LINE__);
    array.data_ = p;
    array.size_ = count;
    return array;
  }
  /// `count` elements from the current device's default pool (the tree build's scratch).
  static DeviceArray from_pool(std::size_t count) {
    DeviceArray array;
    T* p = nullptr;
    QTMV_CUDA_CHECK(cudaMallocAsync(&p, count * sizeof(T), 0));
    array.data_ = p;
    array.size_ = count;
    array.from_pool_ = true;
    return array;
  }

  T* get() const { return data_; }
  std::size_t size() const { return size_; }
  explicit operator bool() const { return data_ != nullptr; }

  /// Frees the array now, unchecked (as the destructor).
  void reset() noexcept {
    if (data_) {
      if (from_pool_) {
        (void)cudaFreeAsync(data_, 0);
      } else {
        (void)cudaFree(data_);
      }
    }
    data_ = nullptr;
    size_ = 0;
  }
  /// Frees the array now, checked: OutOfMemory or std::runtime_error as any CUDA call.
  void free_checked() {
    T* p = data_;
    const bool pooled = from_pool_;
    data_ = nullptr;
    size_ = 0;
    if (!p) return;
    if (pooled) {
      QTMV_CUDA_CHECK(cudaFreeAsync(p, 0));
    } else {
      QTMV_CUDA_CHECK(cudaFree(p));
    }
  }

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
  bool from_pool_ = false;
};

/// A plain array of `count` elements, its bytes added to *total.
template <typename T>
DeviceArray<T> device_alloc(std::size_t count, std::size_t* total, FaultStep injected) {
  DeviceArray<T> array = DeviceArray<T>::plain(count, injected);
  *total += count * sizeof(T);
  return array;
}

/// A plain array holding a copy of `host`, its bytes added to *total.
template <typename T, typename Alloc>
DeviceArray<T> device_copy(const std::vector<T, Alloc>& host, std::size_t* total, FaultStep injected) {
  DeviceArray<T> array = device_alloc<T>(host.size(), total, injected);
  if (array) QTMV_CUDA_CHECK(cudaMemcpy(array.get(), host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice));
  return array;
}

/// The tree build's scratch: a pool array that grows on demand, to twice what is asked and more,
/// so that the levels seldom allocate (contents dropped by need, kept by grow_keep).
template <typename T>
struct Buffer {
  DeviceArray<T> array;
  T* get() const { return array.get(); }
  void need(std::size_t n) {
    if (n <= array.size()) return;
    array.free_checked();
    array = DeviceArray<T>::from_pool(2 * n + 256);
  }
  void grow_keep(std::size_t n, std::size_t used) {
    if (n <= array.size()) return;
    DeviceArray<T> grown = DeviceArray<T>::from_pool(2 * n + 256);
    if (used) {
      QTMV_CUDA_CHECK(cudaMemcpyAsync(grown.get(), array.get(), used * sizeof(T), cudaMemcpyDeviceToDevice, 0));
    }
    array.free_checked();
    array = std::move(grown);
  }
  /// The first `count` elements in a plain array of their own (of at least one element).
  DeviceArray<T> copy_out(std::size_t count, FaultStep injected) const {
    DeviceArray<T> copy = DeviceArray<T>::plain(count ? count : 1, injected);
    if (count) {
      QTMV_CUDA_CHECK(cudaMemcpyAsync(copy.get(), array.get(), count * sizeof(T), cudaMemcpyDeviceToDevice, 0));
    }
    return copy;
  }
};

constexpr int kBlock = 256;

/// QTMV_LABEL_TRACE set: the device build reports each step's time and size on stderr (for
/// tuning; the device is synchronised at each report). A Labeller constructor makes one, which
/// reads the variable, and passes it on to the build.
struct Trace {
  bool on = std::getenv("QTMV_LABEL_TRACE") != nullptr;
  std::chrono::steady_clock::time_point last = std::chrono::steady_clock::now();
  void operator()(const char* step, unsigned long long a = 0, unsigned long long b = 0) {
    if (!on) return;
    QTMV_CUDA_CHECK(cudaDeviceSynchronize());
    const auto now = std::chrono::steady_clock::now();
    std::fprintf(stderr, "trace: %-24s %9.3f ms  %llu %llu\n", step,
                 std::chrono::duration<double, std::milli>(now - last).count(), a, b);
    last = now;
  }
};

/// Threads for the host's share of the build (the groups' plan): `asked`, or all when 0.
int host_threads(int asked) {
  return asked > 0 ? asked : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// Page-locked host memory (cudaMallocHost): device-to-host copies into it run at the bus's
/// speed, where copies into pageable memory go through the driver's own staging on one thread.
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  ~PinnedBuffer() {
    if (data_) (void)cudaFreeHost(data_);
  }
  /// At least `bytes` (kept once allocated).
  void* get(std::size_t bytes) {
    if (bytes > size_) {
      if (data_) QTMV_CUDA_CHECK(cudaFreeHost(data_));
      data_ = nullptr;
      size_ = 0;
      QTMV_CUDA_CHECK(cudaMallocHost(&data_, bytes));
      size_ = bytes;
    }
    return data_;
  }

 private:
  void* data_ = nullptr;
  std::size_t size_ = 0;
};

/// memcpy on several threads: the destination's first touch (page faults) and the copy of
/// gigabytes of outline cells, which one thread does at a few GB/s.
void parallel_copy(void* to, const void* from, std::size_t bytes) {
  constexpr std::size_t kPiece = std::size_t{16} << 20;
  const std::size_t pieces = (bytes + kPiece - 1) / kPiece;
  const std::size_t threads = std::min<std::size_t>(pieces, static_cast<std::size_t>(host_threads(0)));
  const auto work = [&](std::size_t t) {
    for (std::size_t k = t; k < pieces; k += threads) {
      const std::size_t first = k * kPiece;
      std::memcpy(static_cast<char*>(to) + first, static_cast<const char*>(from) + first,
                  std::min(kPiece, bytes - first));
    }
  };
  if (threads <= 1) {
    work(0);
    return;
  }
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& th : pool) th.join();
}

unsigned int blocks_for(std::uint64_t count) {
  const std::uint64_t blocks = (count + kBlock - 1) / kBlock;
  return static_cast<unsigned int>(blocks < 0x7fffffffu ? blocks : 0x7fffffffu);
}

// --- hier -----------------------------------------------------------------------------------

__global__ void tree_label_kernel(TreeView tree, grid::Code first, std::uint64_t count, std::int32_t* site,
                                  float* metres, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    tree_label_cell(tree, first + k, site + k, metres ? metres + k : nullptr, boundary ? boundary + k : nullptr);
  }
}

/// Labels (and boundary flags, no distances) in code order, written coalesced: each warp takes
/// spans of kPaintSpan = 128 x kPaintRounds consecutive outputs in turn, 4 per lane per round (one
/// 16-byte site store and one 4-byte flag store per lane). A span that lies in one row first
/// tabulates the jump cells it crosses (a row's cells fall into consecutive jump cells of one
/// jump row): the site of those in a uniform leaf and clean (jump_clean), so that their cells
/// take it with flag 0 from a shared-memory look-up. Other cells go one by one: a cell in a
/// uniform leaf gets the leaf's site, and flag 0 when it lies inside that leaf, else
/// kBoundaryPending; cells of list leaves are queued per warp in shared memory and then take
/// tree_label, 32 at a time, so that whole warps work on them; their flags are left pending too.
/// A span with pending flags is appended to pending_spans (*pending_count of them) for
/// tree_flag_kernel. Same labels as tree_label_kernel, and, once tree_flag_kernel has run, the
/// same flags.
constexpr int kPaintRounds = 8;
constexpr int kPaintWarps = kBlock / 32;
constexpr int kPaintSpan = 32 * 4 * kPaintRounds;  // outputs per warp
constexpr int kPaintTable = 256;                   // jump cells a one-row span may tabulate
static_assert(kPaintSpan == 4 * kBlock, "tree_flag_kernel's blocks take a span at a time");
constexpr std::uint64_t kPaintMinCells = std::uint64_t{1} << 21;  // fewer go cell by cell

/// Steps cell c (of a level with `rows` rows per octant) `step` codes on.
__device__ inline void advance_cell(grid::Cell& c, std::uint32_t step, std::uint32_t rows) {
  c.col += step;
  while (c.col > 2 * c.row) {
    c.col -= 2 * c.row + 1;
    if (++c.row == rows) {
      c.row = 0;
      ++c.octant;
    }
  }
}

/// tree_paint_kernel's work for span `span` (outputs [span, span + 1) x kPaintSpan) of one warp;
/// q and table: the warp's shared memory.
__device__ inline void paint_span(const TreeView& tree, const std::uint8_t* jump_clean, grid::Code first,
                                  std::uint64_t count, std::int32_t* site, std::uint8_t* boundary,
                                  std::uint32_t* pending_spans, unsigned int* pending_count, std::uint64_t span,
                                  std::uint16_t* q, std::int32_t* table) {
  const int level = tree.level, jl = tree.jump_level, k = level - jl;
  const unsigned lane = threadIdx.x & 31u;
  const std::uint64_t warp_out = span * kPaintSpan;
  int queued = 0;
  bool pending = false;
  const std::uint32_t rows = 1u << level;
  // The jump cell last looked up, its entry's node and whether it is clean.
  grid::Cell jump_cell{-1, 0, 0};
  int jump_level = 0, node_count = 0, node_value = 0;
  bool clean = false;
  auto look_up = [&](const grid::Cell& a) {
    if (a.col == jump_cell.col && a.row == jump_cell.row && a.octant == jump_cell.octant) return;
    jump_cell = a;
    const grid::Code jcode = grid::code_of(a, jl);
    const int2 e = __ldg(reinterpret_cast<const int2*>(tree.jump + jcode));
    jump_level = e.y;
    const int2 n = __ldg(reinterpret_cast<const int2*>(tree.nodes + e.x));
    node_count = n.x;
    node_value = n.y;
    clean = boundary && __ldg(jump_clean + jcode);
  };
  // The span's first cell, and the table when the span lies in one row.
  const grid::Cell c0 = grid::cell_of(first + warp_out, level);
  const std::uint64_t span_cells = count - warp_out < kPaintSpan ? count - warp_out : kPaintSpan;
  const std::uint32_t span_n = static_cast<std::uint32_t>(span_cells);
  const std::uint32_t local_row = c0.row & ((1u << k) - 1u);
  const std::uint32_t jc0 = grid::ancestor_col(c0.col, local_row, k);
  const bool one_row = c0.col + (span_cells - 1) <= 2 * c0.row;
  const bool tabulated =
      one_row && grid::ancestor_col(c0.col + static_cast<std::uint32_t>(span_cells - 1), local_row, k) - jc0 < kPaintTable;
  if (tabulated) {
    const std::uint32_t entries = grid::ancestor_col(c0.col + static_cast<std::uint32_t>(span_cells - 1), local_row, k) - jc0 + 1;
    for (std::uint32_t t = lane; t < entries; t += 32) {
      const grid::Code jcode = grid::code_of(grid::Cell{c0.octant, c0.row >> k, jc0 + t}, jl);
      const TreeNode n = tree.nodes[__ldg(&tree.jump[jcode].node)];
      table[t] = n.count == kUniform && (!boundary || __ldg(jump_clean + jcode)) ? n.value : -1;
    }
    __syncwarp();
  }
  grid::Cell c = c0;
  advance_cell(c, 4 * lane, rows);  // the lane's first cell of the round
  for (int round = 0; round < kPaintRounds; ++round) {
    const std::uint32_t local = static_cast<std::uint32_t>(round * 128) + 4 * lane;
    const std::uint64_t out = warp_out + local;
    std::int32_t s[4] = {-1, -1, -1, -1};
    std::uint32_t flags = 0;  // byte j: the flag of cell out + j (0 or kBoundaryPending)
    unsigned slow = 0;        // bit j: cell out + j is queued
    if (local < span_n) {
      unsigned todo = 0;  // bit j: cell out + j goes one by one
      if (tabulated) {
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if (local + j < span_n) {
            s[j] = table[grid::ancestor_col(c.col + j, local_row, k) - jc0];
            if (s[j] < 0) todo |= 1u << j;
          }
        }
      } else {
        todo = local + 4 <= span_n ? 0xfu : (1u << (span_n - local)) - 1u;
      }
      // Skipped as a whole in the common case, a span's table settling all four.
      if (todo != 0) {
        grid::Cell cc = c;
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if ((todo >> j) & 1u) {
            look_up(grid::ancestor(cc, level, jl));
            // find_leaf's walk, from the jump entry.
            int leaf_level = jump_level, leaf_count = node_count, leaf_value = node_value;
            while (leaf_count == kInternal) {
              const int2 n = __ldg(reinterpret_cast<const int2*>(tree.nodes + leaf_value +
                                                                 grid::child_digit(grid::ancestor(cc, level, leaf_level + 1))));
              leaf_count = n.x;
              leaf_value = n.y;
              ++leaf_level;
            }
            if (leaf_count == kUniform) {
              s[j] = leaf_value;
              if (boundary && !clean && !grid::interior_of_ancestor(cc, level, leaf_level)) {
                flags |= std::uint32_t{kBoundaryPending} << (8 * j);
              }
            } else {
              slow |= 1u << j;
              if (boundary) flags |= std::uint32_t{kBoundaryPending} << (8 * j);
            }
          }
          if (j < 3) advance_cell(cc, 1, rows);
        }
      }
      if (local + 4 <= span_n) {
        *reinterpret_cast<int4*>(site + out) = make_int4(s[0], s[1], s[2], s[3]);
        if (boundary) *reinterpret_cast<std::uint32_t*>(boundary + out) = flags;
      } else {
#pragma unroll
        for (int j = 0; j < 4; ++j) {
          if (local + j < span_n) {
            site[out + j] = s[j];
            if (boundary) boundary[out + j] = static_cast<std::uint8_t>(flags >> (8 * j));
          }
        }
      }
    }
    pending = pending || flags != 0;
    if (tabulated) {
      c.col += 128;  // the span's cells are all in this row
    } else {
      advance_cell(c, 128, rows);
    }
    // Queue the cells of list leaves in code order (warp-aggregated).
    if (__any_sync(0xffffffffu, slow != 0)) {
#pragma unroll
      for (int j = 0; j < 4; ++j) {
        const bool mine = (slow >> j) & 1u;
        const unsigned ballot = __ballot_sync(0xffffffffu, mine);
        if (mine) q[queued + __popc(ballot & ((1u << lane) - 1u))] = static_cast<std::uint16_t>(local + j);
        queued += __popc(ballot);
      }
    }
  }
  pending = __any_sync(0xffffffffu, pending);
  if (pending_spans && lane == 0 && pending) {
    pending_spans[atomicAdd(pending_count, 1u)] = static_cast<std::uint32_t>(span);
  }
  __syncwarp();  // the queue, before other lanes read it
  for (int e = static_cast<int>(lane); e < queued; e += 32) {
    const std::uint64_t out = warp_out + q[e];
    site[out] = tree_label(tree, grid::cell_of(first + out, level));
  }
  __syncwarp();  // the queue and the table, before the warp's next span
}

/// The paint pass: a grid that fills the device, each warp taking spans in turn from *next_span
/// (a span's work varies, lists and walks near boundaries, so fixed blocks would leave their
/// slots held by their slowest warp).
__global__ void __launch_bounds__(kBlock, 4) tree_paint_kernel(TreeView tree, const std::uint8_t* jump_clean,
                                                               grid::Code first, std::uint64_t count,
                                                               std::int32_t* site, std::uint8_t* boundary,
                                                               std::uint32_t* pending_spans,
                                                               unsigned int* pending_count,
                                                               unsigned int* next_span) {
  __shared__ std::uint16_t queue[kPaintWarps][kPaintSpan];
  __shared__ std::int32_t table[kPaintWarps][kPaintTable];
  const unsigned lane = threadIdx.x & 31u, warp = threadIdx.x >> 5;
  const std::uint64_t spans = (count + kPaintSpan - 1) / kPaintSpan;
  for (;;) {
    unsigned int span = 0;
    if (lane == 0) span = atomicAdd(next_span, 1u);
    span = __shfl_sync(0xffffffffu, span, 0);
    if (span >= spans) return;  // whole warps leave together: the ballots need all lanes
    paint_span(tree, jump_clean, first, count, site, boundary, pending_spans, pending_count, span, queue[warp],
               table[warp]);
  }
}

/// tree_flag_kernel's work for one warp: settles the pending flags (kBoundaryPending) among
/// outputs [warp_out, warp_out + 128), 4 per lane. The pending cells are queued in q in code order
/// (ballots) and then taken 32 at a time, so that whole warps do the neighbour look-ups rather
/// than the few lanes that hold one. A cell's flag is 1 when one of its three edge neighbours has
/// another site: a neighbour inside [first, first + count) reads the label tree_paint_kernel wrote
/// there; one outside is labelled from the tree (tree_label), and only when the neighbours inside
/// did not settle it, those look-ups being the dear ones.
__device__ inline void settle_flags(const TreeView& tree, grid::Code first, std::uint64_t count,
                                    const std::int32_t* site, std::uint8_t* boundary, std::uint64_t warp_out,
                                    std::uint8_t* q) {
  const unsigned lane = threadIdx.x & 31u;
  const std::uint64_t out = warp_out + 4 * lane;
  std::uint32_t flags = 0;
  if (out + 4 <= count) {
    flags = *reinterpret_cast<const std::uint32_t*>(boundary + out);
  } else {
    for (std::uint64_t j = 0; out + j < count; ++j) flags |= std::uint32_t{boundary[out + j]} << (8 * j);
  }
  int queued = 0;
#pragma unroll
  for (int j = 0; j < 4; ++j) {
    const bool mine = ((flags >> (8 * j)) & 0xffu) == kBoundaryPending;
    const unsigned ballot = __ballot_sync(0xffffffffu, mine);
    if (mine) q[queued + __popc(ballot & ((1u << lane) - 1u))] = static_cast<std::uint8_t>(4 * lane + j);
    queued += __popc(ballot);
  }
  __syncwarp();
  const int level = tree.level;
  for (int e = static_cast<int>(lane); e < queued; e += 32) {
    const std::uint64_t local = warp_out + q[e];
    const grid::Code code = first + local;
    const grid::Cell c = grid::cell_of(code, level);
    const std::int32_t own = __ldg(site + local);
    grid::Code nb[3];
    grid::neighbours(c, code, level, nb);
    bool flag = false, inside[3];
#pragma unroll
    for (int n = 0; n < 3; ++n) {
      inside[n] = nb[n] >= first && nb[n] - first < count;
      if (inside[n]) flag = flag || __ldg(site + (nb[n] - first)) != own;
    }
#pragma unroll
    for (int n = 0; n < 3; ++n) {
      if (!flag && !inside[n]) flag = tree_label(tree, grid::cell_of(nb[n], level)) != own;
    }
    boundary[local] = flag;
  }
  __syncwarp();  // the queue, before the warp's next use of it
}

/// The pending flags that tree_paint_kernel left, from the labels it wrote: a cell is a boundary
/// cell when one of its three edge neighbours has another site. A neighbour inside
/// [first, first + count) reads its label there; one outside is looked up in the tree
/// (tree_label, as tree_label_cell does). The paint spans with a pending flag are listed in
/// pending_spans (in no particular order: each span's flags depend on the labels alone); the
/// blocks take them a span at a time, each warp gathering the pending cells of its 128 outputs
/// and settling them 32 at a time.
__global__ void __launch_bounds__(kBlock) tree_flag_kernel(TreeView tree, grid::Code first, std::uint64_t count,
                                                           const std::int32_t* site, std::uint8_t* boundary,
                                                           const std::uint32_t* pending_spans,
                                                           const unsigned int* pending_count) {
  __shared__ std::uint8_t queue[kPaintWarps][128];
  const unsigned warp = threadIdx.x >> 5;
  const unsigned int spans = *pending_count;
  for (unsigned int k = blockIdx.x; k < spans; k += gridDim.x) {
    const std::uint64_t warp_out = static_cast<std::uint64_t>(pending_spans[k]) * kPaintSpan + warp * 128;
    if (warp_out < count) settle_flags(tree, first, count, site, boundary, warp_out, queue[warp]);
  }
}

// --- brute: the paper's Kernel Function 1, candidates tiled through shared memory ----------

/// The best of all pieces for x, the pieces read through shared memory a block's tile at a time.
/// Every thread of the block must call it (it synchronises), active or not.
__device__ Best tiled_best(const Vec3& x, const Piece* pieces, int piece_count) {
  __shared__ Piece tile[kBlock];
  Best best = no_best();
  for (int base = 0; base < piece_count; base += kBlock) {
    const int n = piece_count - base < kBlock ? piece_count - base : kBlock;
    __syncthreads();
    if (static_cast<int>(threadIdx.x) < n) tile[threadIdx.x] = pieces[base + threadIdx.x];
    __syncthreads();
    consider_all(best, x, tile, n);
  }
  return best;
}

__global__ void brute_label_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                   std::uint64_t count, std::int32_t* site, float* metres) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Best best = tiled_best(grid::cell_centre_vector(active ? first + k : first, level), pieces, piece_count);
  if (!active) return;
  site[k] = best.site;
  if (metres) metres[k] = static_cast<float>(chord2_to_metres(best.chord2));
}

/// Boundary flags from the labels of [first, first + count); neighbours outside the range are
/// labelled again by brute force (only the tile's edges).
__global__ void brute_boundary_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                      std::uint64_t count, const std::int32_t* site, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    grid::Cell nb[3];
    grid::neighbours(grid::cell_of(first + k, level), level, nb);
    std::uint8_t flag = 0;
    for (int s = 0; s < 3 && !flag; ++s) {
      const grid::Code code = grid::code_of(nb[s], level);
      std::int32_t other;
      if (code >= first && code - first < count) {
        other = site[code - first];
      } else {
        Best best = no_best();
        consider_all(best, grid::cell_centre_vector(code, level), pieces, piece_count);
        other = best.site;
      }
      flag = other != site[k];
    }
    boundary[k] = flag;
  }
}

/// The float64 brute-force label of each code of a list (the benchmark's reference).
__global__ void brute_codes_kernel(const Piece* pieces, int piece_count, int level, const grid::Code* codes,
                                   std::uint64_t count, std::int32_t* site) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Best best = tiled_best(grid::cell_centre_vector(active ? codes[k] : 0, level), pieces, piece_count);
  if (active) site[k] = best.site;
}

// --- the tree, built on the device ----------------------------------------------------------
//
// The same tree as build_tree (labeller.cpp), node for node and list entry for list entry: one
// level at a time, every (node, parent-list entry) pair is one work item; per node the nearest
// candidate's squared chord (an atomicMin on the float64 bits: the chords are >= 0, so their bit
// patterns order as the values), then the kept entries (d2 <= prune_threshold) are compacted in
// list order by a scan, and the nodes' kinds (decide_node, as on the host; a node covered by one
// site's fixed cells from cover_lookup) and offsets and children follow from scans in node
// order, as the host's parts do.

/// A node of the level being built (see labeller.cpp's Pending).
struct DevPending {
  grid::Cell cell;
  std::int32_t node;
  std::uint32_t parent_count;
  std::uint64_t parent_offset;
};

/// Per node totals, scanned in node order.
struct LevelSums {
  unsigned long long leaf_entries;      // list entries of list leaves
  unsigned long long internal_entries;  // list entries kept by internal nodes
  unsigned long long internals;         // internal nodes
  __host__ __device__ LevelSums operator+(const LevelSums& o) const {
    return {leaf_entries + o.leaf_entries, internal_entries + o.internal_entries, internals + o.internals};
  }
};
struct AddSums {
  __host__ __device__ LevelSums operator()(const LevelSums& a, const LevelSums& b) const { return a + b; }
};

__global__ void level_init_kernel(const DevPending* pending, std::int32_t n, int level, bool last, Vec3* centre,
                                  double* radius, unsigned long long* start_in, unsigned long long* min_bits,
                                  std::int32_t* site_min, std::int32_t* site_max, unsigned long long* key) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  centre[q] = grid::cell_centre_vector(grid::code_of(p.cell, level), level);
  radius[q] = last ? 0.0 : node_radius(level, p.cell);
  start_in[q] = p.parent_count;
  if (q == 0) start_in[n] = 0;
  min_bits[q] = ~0ull;
  site_min[q] = INT_MAX;
  site_max[q] = INT_MIN;
  key[q] = ~0ull;
}

/// Segmented reductions over a warp whose items are sorted by node (inactive lanes: node -1).
/// Returns true in the lane that holds its node's result.
template <typename T, typename Op>
__device__ inline bool warp_segment_reduce(std::int32_t node, T& value, Op op) {
  const int lane = threadIdx.x & 31;
  for (int off = 1; off < 32; off <<= 1) {
    const T other = __shfl_down_sync(0xffffffffu, value, off);
    const std::int32_t other_node = __shfl_down_sync(0xffffffffu, node, off);
    if (lane + off < 32 && other_node == node) value = op(value, other);
  }
  const std::int32_t prev = __shfl_up_sync(0xffffffffu, node, 1);
  return node >= 0 && (lane == 0 || prev != node);
}

struct MinU64 {
  __device__ unsigned long long operator()(unsigned long long a, unsigned long long b) const { return a < b ? a : b; }
};
struct MinI32 {
  __device__ std::int32_t operator()(std::int32_t a, std::int32_t b) const { return a < b ? a : b; }
};
struct MaxI32 {
  __device__ std::int32_t operator()(std::int32_t a, std::int32_t b) const { return a > b ? a : b; }
};

// The nodes of a level come in groups of four that share one parent list (the four children of
// an internal node; at level 0 the octants 0-3 and 4-7, each with every candidate), so a work
// item is one entry of a group's list, and its piece is read once for the four nodes. Node
// 4 g + c's entries start at start[4 g + c] = 4 start[4 g] / 4 + c * (its list's length).

/// The group holding work item t (start[4 g] <= 4 t < start[4 g + 4]) is owner[t]: each group
/// with items marks its first item, and a running maximum fills the rest.
__global__ void level_owner_kernel(const unsigned long long* start, std::int32_t groups, std::int32_t* heads) {
  const std::int32_t g = blockIdx.x * blockDim.x + threadIdx.x;
  if (g < groups && start[4 * g + 4] > start[4 * g]) heads[start[4 * g] / 4] = g;
}

/// Work item t of a level: the group of four sibling nodes it serves (*group), the position in
/// their shared parent list (*position) and the item found there.
__device__ inline std::int32_t list_item(const DevPending* pending, const std::int32_t* owner,
                                         const unsigned long long* start, unsigned long long t,
                                         const std::int32_t* parent_lists, std::int32_t* group,
                                         unsigned long long* position) {
  const std::int32_t g = owner[t];
  *group = g;
  *position = t - start[4 * g] / 4;
  return parent_lists[pending[4 * g].parent_offset + *position];
}

/// Pass 1: per node the least upper bound of the items' distances (squared chords).
__global__ void level_min_kernel(const DevPending* pending, const std::int32_t* owner, const unsigned long long* start,
                                 unsigned long long items, const std::int32_t* parent_lists, const Piece* pieces,
                                 const PieceGroup* runs, const Vec3* centre, unsigned long long* min_bits) {
  const unsigned long long t = static_cast<unsigned long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  std::int32_t g = -1;
  unsigned long long bits[4] = {~0ull, ~0ull, ~0ull, ~0ull};
  if (t < items) {
    unsigned long long pos;
    const std::int32_t item = list_item(pending, owner, start, t, parent_lists, &g, &pos);
    for (int c = 0; c < 4; ++c) {
      double lb2, ub2;
      std::int32_t site;
      item_bounds(centre[4 * g + c], item, pieces, runs, &lb2, &ub2, &site);
      bits[c] = static_cast<unsigned long long>(__double_as_longlong(ub2));
    }
  }
  for (int c = 0; c < 4; ++c) {
    if (warp_segment_reduce(g, bits[c], MinU64{})) atomicMin(&min_bits[4 * g + c], bits[c]);
  }
}

/// Pass 2 (levels above the labelling level): per entry the items it leaves to the node (0, 1,
/// or a loose group's refined subtree: refine_kept), and the kept sites' range per node.
__global__ void level_keep_kernel(const DevPending* pending, const std::int32_t* owner, const unsigned long long* start,
                                  unsigned long long items, const std::int32_t* parent_lists, const Piece* pieces,
                                  const PieceGroup* runs, const Vec3* centre, const double* radius,
                                  const double* threshold, unsigned long long* keep, std::int32_t* site_min,
                                  std::int32_t* site_max) {
  const unsigned long long t = static_cast<unsigned long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  std::int32_t g = -1;
  std::int32_t lo[4] = {INT_MAX, INT_MAX, INT_MAX, INT_MAX}, hi[4] = {INT_MIN, INT_MIN, INT_MIN, INT_MIN};
  if (t < items) {
    unsigned long long pos;
    const std::int32_t item = list_item(pending, owner, start, t, parent_lists, &g, &pos);
    for (int c = 0; c < 4; ++c) {
      double lb2, ub2;
      std::int32_t site;
      item_bounds(centre[4 * g + c], item, pieces, runs, &lb2, &ub2, &site);
      const std::int32_t kept =
          lb2 <= threshold[4 * g + c]
              ? refine_kept(centre[4 * g + c], item, pieces, runs, radius[4 * g + c], threshold[4 * g + c], nullptr)
              : 0;
      keep[start[4 * g + c] + pos] = static_cast<unsigned long long>(kept);
      if (kept > 0) lo[c] = hi[c] = site;
    }
  }
  for (int c = 0; c < 4; ++c) {
    const bool lead = warp_segment_reduce(g, lo[c], MinI32{});
    warp_segment_reduce(g, hi[c], MaxI32{});
    if (lead && lo[c] != INT_MAX) {
      atomicMin(&site_min[4 * g + c], lo[c]);
      atomicMax(&site_max[4 * g + c], hi[c]);
    }
  }
}

/// Per node: the pruning threshold.
__global__ void level_threshold_kernel(std::int32_t n, const unsigned long long* min_bits, const double* radius,
                                       double* threshold) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  threshold[q] = prune_threshold(__longlong_as_double(static_cast<long long>(min_bits[q])), radius[q]);
}

/// At the labelling level, per node (one cell): best_of_items over its parent's list, as the host
/// does; key = site << 32 | winning piece.
__global__ void level_settle_kernel(const DevPending* pending, std::int32_t n, const std::int32_t* parent_lists,
                                    const Piece* pieces, const PieceGroup* runs, const Vec3* centre,
                                    unsigned long long* key) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  std::int32_t winner = -1;
  const Best best = best_of_items(centre[q], parent_lists + p.parent_offset, static_cast<std::int32_t>(p.parent_count),
                                  pieces, runs, &winner);
  key[q] = (static_cast<unsigned long long>(best.site) << 32) | static_cast<std::uint32_t>(winner);
}

/// Per node: its kind and counts (decide_node, as build_tree; value: the uniform leaf's site).
__global__ void level_decide_kernel(const DevPending* pending, std::int32_t n, int l, bool last, bool with_distance,
                                    bool list_level_reached, CoverView cover, const unsigned long long* start,
                                    const unsigned long long* keep_pos, const std::int32_t* site_min,
                                    const std::int32_t* site_max, const unsigned long long* key, std::int32_t* kind,
                                    std::int32_t* count, std::int32_t* value, LevelSums* sums_in) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  NodeDecision d;
  std::int32_t c;
  const CoverLookup covered = cover_lookup(cover, pending[q].cell, l);
  if (last) {
    c = with_distance ? 1 : 0;
    d = decide_node(true, with_distance, list_level_reached, static_cast<std::uint32_t>(c), true,
                    static_cast<std::int32_t>(key[q] >> 32), covered.site);
  } else {
    c = static_cast<std::int32_t>(keep_pos[start[q + 1]] - keep_pos[start[q]]);
    const bool one_site = c == 0 || site_min[q] == site_max[q];
    d = decide_node(false, with_distance, list_level_reached, static_cast<std::uint32_t>(c), one_site,
                    c == 0 ? -1 : site_min[q], covered.site, covered.partly, cover.split_partly, covered.claim_site);
  }
  const std::int32_t k = d.kind;
  kind[q] = k;
  count[q] = c;
  value[q] = d.site;
  sums_in[q] = {k == kListLeaf ? static_cast<unsigned long long>(c) : 0ull,
                k == kInternal ? static_cast<unsigned long long>(c) : 0ull, k == kInternal ? 1ull : 0ull};
  if (q == 0) sums_in[n] = {0, 0, 0};
}

/// Per node: its TreeNode, and at the labelling level its winner.
__global__ void level_write_nodes_kernel(const DevPending* pending, std::int32_t n, bool last,
                                         const std::int32_t* kind, const std::int32_t* count,
                                         const std::int32_t* value, const unsigned long long* key,
                                         const LevelSums* offsets, unsigned long long lists_base,
                                         unsigned long long nodes_base, TreeNode* nodes, std::int32_t* lists) {
  const std::int32_t q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  const DevPending p = pending[q];
  const LevelSums at = offsets[q];
  if (kind[q] == kUniform) {
    nodes[p.node] = {kUniform, value[q]};
  } else if (kind[q] == kListLeaf) {
    nodes[p.node] = {count[q], static_cast<std::int32_t>(lists_base + at.leaf_entries)};
    if (last) lists[lists_base + at.leaf_entries] = static_cast<std::int32_t>(key[q] & 0xffffffffu);
  } else {
    nodes[p.node] = {kInternal, static_cast<std::int32_t>(nodes_base + 4 * at.internals)};
  }
}

/// Per child of an internal node (thread 4 q + k: child k of node q): its pending entry. A
/// thread per child keeps the writes of the 24-byte entries contiguous across a warp.
__global__ void level_write_children_kernel(const DevPending* pending, std::int32_t n, const std::int32_t* kind,
                                            const std::int32_t* count, const LevelSums* offsets,
                                            unsigned long long nodes_base, DevPending* next) {
  const std::uint64_t t = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= 4 * static_cast<std::uint64_t>(n)) return;
  const auto q = static_cast<std::int32_t>(t >> 2);
  const int k = static_cast<int>(t & 3u);
  if (kind[q] != kInternal) return;
  const LevelSums at = offsets[q];
  grid::Cell kids[4];
  grid::children(pending[q].cell, kids);
  next[4 * at.internals + k] = {kids[k], static_cast<std::int32_t>(nodes_base + 4 * at.internals) + k,
                                static_cast<std::uint32_t>(count[q]), at.internal_entries};
}

/// Per work item, for each of its four nodes: the kept items (the item, or a loose group's
/// refined subtree: refine_kept) to the list leaves' lists or to the next level's parent lists.
__global__ void level_write_lists_kernel(const DevPending* pending, const std::int32_t* owner,
                                         const unsigned long long* start, unsigned long long items,
                                         const std::int32_t* parent_lists, const Piece* pieces,
                                         const PieceGroup* runs, const Vec3* centre, const double* radius,
                                         const double* threshold, const unsigned long long* keep_pos,
                                         const std::int32_t* kind,
                                         const LevelSums* offsets, unsigned long long lists_base, std::int32_t* lists,
                                         std::int32_t* next_lists) {
  const unsigned long long t = static_cast<unsigned long long>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= items) return;
  std::int32_t g;
  unsigned long long pos;
  const std::int32_t id = list_item(pending, owner, start, t, parent_lists, &g, &pos);
  for (int c = 0; c < 4; ++c) {
    const std::int32_t node = 4 * g + c;
    const unsigned long long e = start[node] + pos;
    const unsigned long long kept = keep_pos[e + 1] - keep_pos[e];
    const std::int32_t k = kind[node];
    if (kept == 0 || k == kUniform) continue;
    const unsigned long long local = keep_pos[e] - keep_pos[start[node]];
    std::int32_t* out = k == kListLeaf ? lists + lists_base + offsets[node].leaf_entries + local
                                           : next_lists + offsets[node].internal_entries + local;
    refine_kept(centre[node], id, pieces, runs, radius[node], threshold[node], out);
  }
}

/// make_group per span, one warp per group (the lanes share its pieces): the same groups as the
/// host's make_groups, since the terms are maxima.
__global__ void make_groups_kernel(const Piece* pieces, const GroupSpan* spans, std::int32_t count,
                                   PieceGroup* groups) {
  const std::uint64_t g = (static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x) >> 5;
  const unsigned lane = threadIdx.x & 31u;
  if (g >= static_cast<std::uint64_t>(count)) return;  // whole warps: count * 32 threads
  const GroupSpan s = spans[g];
  const Piece arc = group_arc(pieces, s);
  GroupTerms t;
  for (std::int32_t k = s.first + static_cast<std::int32_t>(lane); k < s.first + s.count; k += 32) {
    add_group_piece(t, arc, pieces, s, k);
  }
  for (int off = 16; off > 0; off >>= 1) {
    const double reach = __shfl_xor_sync(0xffffffffu, t.reach, off), cap = __shfl_xor_sync(0xffffffffu, t.cap, off);
    const double gap = __shfl_xor_sync(0xffffffffu, t.gap, off);
    t.reach = reach > t.reach ? reach : t.reach;
    t.cap = cap > t.cap ? cap : t.cap;
    t.gap = gap > t.gap ? gap : t.gap;
  }
  if (lane == 0) groups[g] = finish_group(arc, s, t);
}

/// The exact rule's candidates from the labeller's input, as make_candidates makes them.
__global__ void make_pieces_kernel(const SitePiece* site_pieces, std::uint64_t piece_count, const FixedCell* fixed,
                                   std::uint64_t fixed_count, int level, Piece* out) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < piece_count) {
    out[k] = candidate_of(site_pieces[k]);
  } else if (k < piece_count + fixed_count) {
    out[k] = candidate_of(fixed[k - piece_count], level);
  }
}

/// Levels up to which a fixed cell's sort key, site << (3 + 2 level) | quadtree_key, fits 64 bits.
constexpr int kMaxDeviceOrderLevel = 15;

/// fixed_cells_in_quadtree_order on the device: each cell's key (site, then quadtree order) and
/// its index, for a stable radix sort.
__global__ void fixed_keys_kernel(const FixedCell* fixed, std::uint64_t count, int level, unsigned long long* keys,
                                  std::uint32_t* index) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= count) return;
  const FixedCell f = fixed[k];
  keys[k] = (static_cast<unsigned long long>(f.site) << (3 + 2 * level)) |
            grid::quadtree_key(grid::cell_of(f.code, level), level);
  index[k] = static_cast<std::uint32_t>(k);
}

__global__ void gather_fixed_kernel(const FixedCell* fixed, const std::uint32_t* index, std::uint64_t count,
                                    FixedCell* out) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) out[k] = fixed[index[k]];
}

__global__ void jump_kernel(const TreeNode* nodes, int jump_level, std::uint64_t count, JumpEntry* jump) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= count) return;
  jump[k] = walk_to_jump_level(nodes, grid::cell_of(k, jump_level), jump_level);
}

__global__ void jump_clean_kernel(TreeView tree, std::uint64_t count, std::uint8_t* clean) {
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) clean[k] = jump_cell_clean(tree, k);
}

/// The outline selection's test of tile cell i (code first + i): a boundary cell or a row end.
struct OutlinePick {
  const std::uint8_t* boundary;
  grid::Code first;
  int level;
  __device__ bool operator()(std::uint32_t i) const {
    return boundary[i] != 0 || is_row_end(grid::cell_of(first + i, level));
  }
};

/// The selected cells (tile indices from `offset`) as outline cells.
__global__ void gather_outline_kernel(const std::uint32_t* index, std::uint32_t count, grid::Code first,
                                      const std::int32_t* site, const std::uint8_t* boundary, OutlineCell* out) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < count) {
    const std::uint32_t i = index[k];
    out[k] = {first + i, site[i], boundary[i] != 0 ? 1u : 0u};
  }
}

unsigned int blocks_of(std::uint64_t count) { return static_cast<unsigned int>((count + kBlock - 1) / kBlock); }

/// The cover (fixed_cover.hpp) copied to the device, as the device build looks it up.
struct DeviceCover {
  DeviceArray<std::uint64_t> first, last;
  DeviceArray<std::int32_t> site, owner_run;
  std::uint64_t count = 0;
  int level = 0;
  bool split_partly = false;
  CoverView view() const {
    return {first.get(), last.get(), site.get(), owner_run.get(), count, level, split_partly};
  }
};

DeviceCover copy_cover(const CoverView* cover, int level, std::size_t* bytes, FaultStep injected) {
  DeviceCover out;
  out.level = level;
  if (cover == nullptr || cover->count == 0) return out;
  const std::uint64_t n = cover->count;
  out.first = device_alloc<std::uint64_t>(n, bytes, injected);
  out.last = device_alloc<std::uint64_t>(n, bytes, injected);
  out.site = device_alloc<std::int32_t>(n, bytes, injected);
  out.owner_run = device_alloc<std::int32_t>(n, bytes, injected);
  QTMV_CUDA_CHECK(cudaMemcpy(out.first.get(), cover->first, n * sizeof(std::uint64_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(cudaMemcpy(out.last.get(), cover->last, n * sizeof(std::uint64_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(cudaMemcpy(out.site.get(), cover->site, n * sizeof(std::int32_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(
      cudaMemcpy(out.owner_run.get(), cover->owner_run, n * sizeof(std::int32_t), cudaMemcpyHostToDevice));
  out.count = n;
  out.split_partly = cover->split_partly;
  return out;
}

/// What build_on_device made: the tree's arrays.
struct DeviceTree {
  DeviceArray<TreeNode> nodes;
  DeviceArray<std::int32_t> lists;
  DeviceArray<JumpEntry> jump;
  std::uint64_t node_count = 0, list_count = 0, jump_count = 0;
  int jump_level = 0;
  double mean_candidates = 0;
};

/// The tree of build_tree (labeller.cpp), built on the current device; `cover`: the claimed
/// cells (DeviceCover; count 0: none). `injected`: QTMV_FAULT_CUDA_OOM as the Labeller read it.
DeviceTree build_on_device(int device, const Piece* pieces, const PieceGroup* runs,
                           const std::vector<std::int32_t>& top_items, int level, bool with_distance,
                           const CoverView& cover, FaultStep injected, Trace& trace) {
  fail_if_injected(injected, FaultStep::build);
  const int list_level = tree_list_level(level);
  // The scratch comes from the device's default pool and stays there (pool_idle_bytes).
  cudaMemPool_t pool;
  QTMV_CUDA_CHECK(cudaDeviceGetDefaultMemPool(&pool, device));
  {
    std::uint64_t keep_all = ~std::uint64_t{0};
    QTMV_CUDA_CHECK(cudaMemPoolSetAttribute(pool, cudaMemPoolAttrReleaseThreshold, &keep_all));
  }
  // A build that throws (too large: label_cells then builds on the host) gives the pool's memory
  // back too, or the tiles would be sized from too little free memory. Errors are moot there.
  struct TrimOnThrow {
    cudaMemPool_t pool;
    bool done = false;
    ~TrimOnThrow() {
      if (done) return;
      cudaDeviceSynchronize();
      cudaMemPoolTrimTo(pool, std::size_t{256} << 20);
    }
  } trim_on_throw{pool};
  DeviceTree t;  // a build that throws frees the tree's arrays with it
  {
  Buffer<DevPending> pending, next;
  Buffer<std::int32_t> parent_lists, next_lists;
  Buffer<TreeNode> nodes;
  Buffer<std::int32_t> lists;
  Buffer<Vec3> centre;
  Buffer<double> radius, threshold;
  Buffer<unsigned long long> start_in, start, min_bits, key;
  Buffer<std::int32_t> site_min, site_max, kind, count, value;
  Buffer<unsigned long long> keep, keep_pos;  // 64 bits: a loose group may refine to many items
  Buffer<std::int32_t> owner_heads, owner;
  Buffer<LevelSums> sums_in, offsets;
  Buffer<unsigned char> temp;
  auto scan_temp = [&](std::size_t bytes) { temp.need(bytes ? bytes : 1); };

  // Level 0: the eight octants, each with the runs' top items.
  std::uint64_t n = grid::kOctants;
  const auto top_count = static_cast<std::uint32_t>(top_items.size());
  std::uint64_t entries = n * top_count;
  {
    DevPending roots[grid::kOctants];
    for (int o = 0; o < grid::kOctants; ++o) roots[o] = {grid::Cell{o, 0, 0}, o, top_count, 0};
    pending.need(n);
    QTMV_CUDA_CHECK(cudaMemcpy(pending.get(), roots, sizeof roots, cudaMemcpyHostToDevice));
    parent_lists.need(top_count);
    QTMV_CUDA_CHECK(
        cudaMemcpy(parent_lists.get(), top_items.data(), top_count * sizeof(std::int32_t), cudaMemcpyHostToDevice));
  }
  std::uint64_t node_count = grid::kOctants, list_count = 0;
  nodes.grow_keep(node_count, 0);
  double weighted = 0;
  for (int l = 0; l <= level && n > 0; ++l) {
    const bool last = l == level;
    // Nodes are counted in 32 bits (keep_pos: 64).
    if (n > 0x7ffffffful) {
      // std::length_error: label_cells falls back to the host build.
      throw std::length_error("the labeller's tree level " + std::to_string(l) +
                              " has too many nodes or entries to be built on the device");
    }
    const std::int32_t nn = static_cast<std::int32_t>(n);
    if (n % 4 != 0 || entries % 4 != 0) throw std::logic_error("build_on_device: nodes not in groups of four");
    centre.need(n);
    radius.need(n);
    threshold.need(n);
    start_in.need(n + 1);
    start.need(n + 1);
    min_bits.need(n);
    key.need(n);
    site_min.need(n);
    site_max.need(n);
    kind.need(n);
    count.need(n);
    value.need(n);
    sums_in.need(n + 1);
    offsets.need(n + 1);
    keep.need(entries + 1);
    keep_pos.need(entries + 1);
    level_init_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, l, last, centre.get(), radius.get(), start_in.get(),
                                                min_bits.get(), site_min.get(), site_max.get(), key.get());
    QTMV_CUDA_CHECK_LAUNCH("level_init_kernel");
    std::size_t bytes = 0;
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, start_in.get(), start.get(), n + 1));
    scan_temp(bytes);
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.get(), bytes, start_in.get(), start.get(), n + 1));
    if (entries > 0) {
      // Groups of four nodes share a list (n and entries are multiples of 4).
      const std::int32_t groups = nn / 4;
      const std::uint64_t items = entries / 4;
      if (last) {
        level_settle_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, parent_lists.get(), pieces, runs, centre.get(),
                                                      key.get());
        QTMV_CUDA_CHECK_LAUNCH("level_settle_kernel");
      } else {
        owner_heads.need(items);
        owner.need(items);
        QTMV_CUDA_CHECK(cudaMemsetAsync(owner_heads.get(), 0, items * sizeof(std::int32_t)));
        level_owner_kernel<<<blocks_of(groups), kBlock>>>(start.get(), groups, owner_heads.get());
        QTMV_CUDA_CHECK_LAUNCH("level_owner_kernel");
        std::size_t owner_bytes = 0;
        QTMV_CUDA_CHECK(
            cub::DeviceScan::InclusiveScan(nullptr, owner_bytes, owner_heads.get(), owner.get(), MaxI32{}, items));
        scan_temp(owner_bytes);
        QTMV_CUDA_CHECK(
            cub::DeviceScan::InclusiveScan(temp.get(), owner_bytes, owner_heads.get(), owner.get(), MaxI32{}, items));
        level_min_kernel<<<blocks_of(items), kBlock>>>(pending.get(), owner.get(), start.get(), items,
                                                       parent_lists.get(), pieces, runs, centre.get(), min_bits.get());
        QTMV_CUDA_CHECK_LAUNCH("level_min_kernel");
        level_threshold_kernel<<<blocks_of(n), kBlock>>>(nn, min_bits.get(), radius.get(), threshold.get());
        QTMV_CUDA_CHECK_LAUNCH("level_threshold_kernel");
        level_keep_kernel<<<blocks_of(items), kBlock>>>(pending.get(), owner.get(), start.get(), items,
                                                        parent_lists.get(), pieces, runs, centre.get(), radius.get(),
                                                        threshold.get(), keep.get(), site_min.get(), site_max.get());
        QTMV_CUDA_CHECK_LAUNCH("level_keep_kernel");
      }
    }
    if (!last) {
      QTMV_CUDA_CHECK(cudaMemset(keep.get() + entries, 0, sizeof(unsigned long long)));
      bytes = 0;
      QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, keep.get(), keep_pos.get(), entries + 1));
      scan_temp(bytes);
      QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.get(), bytes, keep.get(), keep_pos.get(), entries + 1));
    }
    level_decide_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, l, last, with_distance, l >= list_level, cover,
                                                  start.get(), keep_pos.get(), site_min.get(), site_max.get(),
                                                  key.get(), kind.get(), count.get(), value.get(), sums_in.get());
    QTMV_CUDA_CHECK_LAUNCH("level_decide_kernel");
    bytes = 0;
    const LevelSums zero{0, 0, 0};
    QTMV_CUDA_CHECK(
        cub::DeviceScan::ExclusiveScan(nullptr, bytes, sums_in.get(), offsets.get(), AddSums{}, zero, n + 1));
    scan_temp(bytes);
    QTMV_CUDA_CHECK(
        cub::DeviceScan::ExclusiveScan(temp.get(), bytes, sums_in.get(), offsets.get(), AddSums{}, zero, n + 1));
    LevelSums total{};
    QTMV_CUDA_CHECK(cudaMemcpy(&total, offsets.get() + n, sizeof total, cudaMemcpyDeviceToHost));
    if (node_count + 4 * total.internals > 0x7fffffffull || list_count + total.leaf_entries > 0x7fffffffull) {
      throw std::length_error("the labeller's tree outgrew 2^31 nodes or list entries");
    }
    nodes.grow_keep(node_count + 4 * total.internals, node_count);
    lists.grow_keep(list_count + total.leaf_entries + 1, list_count);
    next.need(4 * total.internals + 1);
    next_lists.need(total.internal_entries + 1);
    level_write_nodes_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, last, kind.get(), count.get(), value.get(),
                                                       key.get(), offsets.get(), list_count, node_count, nodes.get(),
                                                       lists.get());
    QTMV_CUDA_CHECK_LAUNCH("level_write_nodes_kernel");
    if (total.internals > 0) {
      level_write_children_kernel<<<blocks_of(4 * n), kBlock>>>(pending.get(), nn, kind.get(), count.get(),
                                                                offsets.get(), node_count, next.get());
      QTMV_CUDA_CHECK_LAUNCH("level_write_children_kernel");
    }
    if (!last && entries > 0) {
      level_write_lists_kernel<<<blocks_of(entries / 4), kBlock>>>(
          pending.get(), owner.get(), start.get(), entries / 4, parent_lists.get(), pieces, runs, centre.get(),
          radius.get(), threshold.get(), keep_pos.get(), kind.get(), offsets.get(), list_count, lists.get(),
          next_lists.get());
      QTMV_CUDA_CHECK_LAUNCH("level_write_lists_kernel");
    }
    weighted += static_cast<double>(entries) +
                static_cast<double>(total.leaf_entries) * std::ldexp(1.0, 2 * (level - l));
    trace(last ? "level (last)" : "level", n, entries);
    node_count += 4 * total.internals;
    list_count += total.leaf_entries;
    n = 4 * total.internals;
    entries = 4 * total.internal_entries;
    std::swap(pending, next);
    std::swap(parent_lists, next_lists);
  }
  t.jump_level = tree_jump_level(level);
  t.jump_count = grid::cell_count(t.jump_level);
  t.jump = DeviceArray<JumpEntry>::plain(t.jump_count, injected);
  jump_kernel<<<blocks_of(t.jump_count), kBlock>>>(nodes.get(), t.jump_level, t.jump_count, t.jump.get());
  QTMV_CUDA_CHECK_LAUNCH("jump_kernel");
  t.node_count = node_count;
  t.list_count = list_count;
  t.mean_candidates = weighted / static_cast<double>(grid::cell_count(level));
  t.nodes = nodes.copy_out(node_count, injected);
  t.lists = lists.copy_out(list_count, injected);
  trace("jump table, copies", t.jump_count, list_count);
  }  // the scratch goes back to the pool here
  QTMV_CUDA_CHECK(cudaDeviceSynchronize());
  trim_on_throw.done = true;
  return t;
}

}  // namespace

int device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    (void)cudaGetLastError();  // no driver or no device: not an error here, just none
    return 0;
  }
  return count;
}

void warm_up(int device) {
  // The runtime creates the device's primary context on its first use; cudaFree(nullptr) is
  // such a use that does nothing else. Failures are left for the labelling to report.
  if (cudaSetDevice(device) != cudaSuccess || cudaFree(nullptr) != cudaSuccess) (void)cudaGetLastError();
}

void release_cached_memory(int device) {
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  QTMV_CUDA_CHECK(release_pool(device));
}

DeviceInfo device_info(int device) {
  cudaDeviceProp prop{};
  QTMV_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  DeviceInfo info;
  info.name = prop.name;
  QTMV_CUDA_CHECK(cudaMemGetInfo(&info.free_bytes, &info.total_bytes));
  info.pool_idle_bytes = pool_idle_bytes(device);
  info.free_bytes += info.pool_idle_bytes;
  return info;
}

struct Labeller::Impl {
  int device = 0;
  int level = 0;
  bool hier = false;
  int piece_count = 0;
  DeviceArray<Piece> pieces;
  DeviceArray<PieceGroup> groups;  ///< the line runs' groups (empty: none)
  DeviceArray<TreeNode> nodes;
  DeviceArray<std::int32_t> lists;
  DeviceArray<JumpEntry> jump;
  int jump_level = 0;
  DeviceArray<std::uint8_t> jump_clean;  ///< per jump cell: jump_cell_clean
  TreeInfo tree_info;
  DeviceArray<std::int32_t> site;
  DeviceArray<float> metres;
  DeviceArray<std::uint8_t> boundary;
  DeviceArray<std::uint32_t> pending_spans;  ///< the paint spans with pending flags, and their count
  DeviceArray<unsigned int> counters;  ///< [0]: pending spans listed, [1]: the paint kernel's next span
  unsigned int flag_blocks = 0;   ///< tree_flag_kernel's grid: enough resident blocks to fill the device
  unsigned int paint_blocks = 0;  ///< tree_paint_kernel's grid: its resident blocks
  std::uint64_t capacity = 0;
  std::size_t bytes = 0;
  std::size_t output_bytes = 0;
  /// select_outline's buffers: a chunk's selected indices, their outline cells, the count, CUB's scratch.
  DeviceArray<std::uint32_t> select_index;
  DeviceArray<OutlineCell> select_cells;
  DeviceArray<std::uint32_t> select_count;
  DeviceArray<unsigned char> select_temp;
  PinnedBuffer select_host;  ///< the outline cells' way to the host
  cudaEvent_t start = nullptr, stop = nullptr;
  /// QTMV_FAULT_CUDA_OOM, read by open() and again by reserve() (FaultStep).
  FaultStep injected_fault = FaultStep::none;

  TreeView view() const {
    return {nodes.get(), lists.get(), pieces.get(), groups.get(), jump.get(), jump_level, level};
  }

  /// The constructors' common start: the device, its events, the level.
  void open(int device_index, int level_index, bool with_tree) {
    injected_fault = fault_step_from_environment();
    device = device_index;
    level = level_index;
    hier = with_tree;
    QTMV_CUDA_CHECK(cudaSetDevice(device));
    int sms = 0;
    QTMV_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    flag_blocks = static_cast<unsigned int>(sms) * 8;
    int per_sm = 0;
    QTMV_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, tree_paint_kernel, kBlock, 0));
    paint_blocks = static_cast<unsigned int>(sms) * static_cast<unsigned int>(per_sm > 0 ? per_sm : 1);
    QTMV_CUDA_CHECK(cudaEventCreate(&start));
    QTMV_CUDA_CHECK(cudaEventCreate(&stop));
  }

  /// The groups of `plan` over the pieces already here, then the tree built here (`cover`: the
  /// fixed cells behind the pieces' fixed points, as build_tree's `fixed`).
  void build_tree(const GroupPlan& plan, bool with_distance, const CoverView& cover, Trace& trace) {
    trace("groups planned", plan.spans.size(), plan.top_items.size());
    if (!plan.spans.empty()) {
      std::size_t span_bytes = 0;
      const DeviceArray<GroupSpan> spans = device_copy(plan.spans, &span_bytes, injected_fault);
      const auto count = static_cast<std::int32_t>(plan.spans.size());
      groups = device_alloc<PieceGroup>(plan.spans.size(), &bytes, injected_fault);
      make_groups_kernel<<<blocks_for(std::uint64_t{32} * plan.spans.size()), kBlock>>>(pieces.get(), spans.get(),
                                                                                         count, groups.get());
      QTMV_CUDA_CHECK_LAUNCH("make_groups_kernel");
    }
    trace("groups made");
    DeviceTree t = build_on_device(device, pieces.get(), groups.get(), plan.top_items, level, with_distance, cover,
                                   injected_fault, trace);
    nodes = std::move(t.nodes);
    lists = std::move(t.lists);
    jump = std::move(t.jump);
    jump_level = t.jump_level;
    mark_clean_jump_cells();
    trace("jump cells marked");
    bytes += t.node_count * sizeof(TreeNode) + t.list_count * sizeof(std::int32_t) + t.jump_count * sizeof(JumpEntry);
    tree_info = {t.node_count, t.list_count, t.jump_count, t.jump_level, t.mean_candidates};
  }
  /// jump_clean for the tree now on the device.
  void mark_clean_jump_cells() {
    const std::uint64_t count = grid::cell_count(jump_level);
    jump_clean = device_alloc<std::uint8_t>(count, &bytes, injected_fault);
    jump_clean_kernel<<<blocks_for(count), kBlock>>>(view(), count, jump_clean.get());
    QTMV_CUDA_CHECK_LAUNCH("jump_clean_kernel");
    QTMV_CUDA_CHECK(cudaDeviceSynchronize());  // part of the preparation, and its errors surface here
  }

  void free_outputs() {
    select_index.reset();
    select_cells.reset();
    select_count.reset();
    select_temp.reset();
    site.reset();
    metres.reset();
    boundary.reset();
    pending_spans.reset();
    counters.reset();
    bytes -= output_bytes;
    output_bytes = 0;
    capacity = 0;
  }
  ~Impl() {
    // Destructors must not throw; errors here are left to the next call's check.
    free_outputs();
    pieces.reset();
    groups.reset();
    nodes.reset();
    lists.reset();
    jump.reset();
    jump_clean.reset();
    if (start) cudaEventDestroy(start);
    if (stop) cudaEventDestroy(stop);
  }
};

Labeller::Labeller(int device, const std::vector<Piece>& candidates, const Tree* tree, int level)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, level, tree != nullptr);
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(candidates.size());
  m.pieces = device_copy(candidates, &m.bytes, m.injected_fault);
  if (tree) {
    m.groups = device_copy(tree->groups, &m.bytes, m.injected_fault);
    m.nodes = device_copy(tree->nodes, &m.bytes, m.injected_fault);
    m.lists = device_copy(tree->lists, &m.bytes, m.injected_fault);
    m.jump = device_copy(tree->jump, &m.bytes, m.injected_fault);
    m.jump_level = tree->jump_level;
    m.mark_clean_jump_cells();
  }
}

Labeller::Labeller(int device, const std::vector<Piece>& candidates, int level, bool with_distance,
                   int threads, const CoverView* cover_given)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, level, true);
  if (candidates.empty()) throw std::invalid_argument("build_tree: no candidates");
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(candidates.size());
  Trace trace;
  m.pieces = device_copy(candidates, &m.bytes, m.injected_fault);
  trace("pieces to the device", candidates.size());
  std::size_t scratch = 0;
  const DeviceCover cover = copy_cover(cover_given, level, &scratch, m.injected_fault);
  trace("cover to the device", cover.count);
  m.build_tree(plan_groups(candidates, host_threads(threads)), with_distance, cover.view(), trace);
}

Labeller::Labeller(int device, const LabelInput& input, bool with_distance, int threads,
                   const CoverView* cover_given)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, input.level, true);
  const std::size_t count = input.piece_count + input.fixed_cell_count;
  if (count == 0) throw std::invalid_argument("build_tree: no candidates");
  if (count > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(count);
  // The input goes over as it is (less to copy than the pieces) and becomes the pieces here, the
  // fixed cells in quadtree order (fixed_cells_in_quadtree_order, sorted here; on the host above
  // kMaxDeviceOrderLevel).
  Trace trace;
  std::vector<FixedCell> host_ordered;
  std::size_t cover_bytes = 0;
  const DeviceCover cover = copy_cover(cover_given, input.level, &cover_bytes, m.injected_fault);
  trace("cover to the device", cover.count);
  const FixedCell* fixed_input = input.fixed_cells;
  const bool order_here = input.level <= kMaxDeviceOrderLevel;
  if (!order_here) fixed_input = fixed_cells_in_quadtree_order(input, threads, &host_ordered);
  {
    std::size_t scratch = 0;
    const DeviceArray<SitePiece> site_pieces = device_alloc<SitePiece>(input.piece_count, &scratch, m.injected_fault);
    DeviceArray<FixedCell> fixed = device_alloc<FixedCell>(input.fixed_cell_count, &scratch, m.injected_fault);
    if (input.piece_count) {
      QTMV_CUDA_CHECK(cudaMemcpy(site_pieces.get(), input.pieces, input.piece_count * sizeof(SitePiece),
                                 cudaMemcpyHostToDevice));
    }
    const std::uint64_t n = input.fixed_cell_count;
    if (n) {
      QTMV_CUDA_CHECK(cudaMemcpy(fixed.get(), fixed_input, n * sizeof(FixedCell), cudaMemcpyHostToDevice));
    }
    if (order_here && n > 1) {
      const DeviceArray<unsigned long long> keys = device_alloc<unsigned long long>(2 * n, &scratch, m.injected_fault);
      const DeviceArray<std::uint32_t> index = device_alloc<std::uint32_t>(2 * n, &scratch, m.injected_fault);
      fixed_keys_kernel<<<blocks_for(n), kBlock>>>(fixed.get(), n, input.level, keys.get(), index.get());
      QTMV_CUDA_CHECK_LAUNCH("fixed_keys_kernel");
      std::size_t temp_bytes = 0;
      const int end_bit = 3 + 2 * input.level + 31;
      QTMV_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, keys.get(), keys.get() + n, index.get(),
                                                      index.get() + n, n, 0, end_bit));
      const DeviceArray<unsigned char> temp = device_alloc<unsigned char>(temp_bytes, &scratch, m.injected_fault);
      QTMV_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(temp.get(), temp_bytes, keys.get(), keys.get() + n, index.get(),
                                                      index.get() + n, n, 0, end_bit));
      DeviceArray<FixedCell> sorted = device_alloc<FixedCell>(n, &scratch, m.injected_fault);
      gather_fixed_kernel<<<blocks_for(n), kBlock>>>(fixed.get(), index.get() + n, n, sorted.get());
      QTMV_CUDA_CHECK_LAUNCH("gather_fixed_kernel");
      QTMV_CUDA_CHECK(cudaDeviceSynchronize());
      fixed = std::move(sorted);
      trace("fixed cells in quadtree order", n);
    }
    m.pieces = device_alloc<Piece>(count, &m.bytes, m.injected_fault);
    make_pieces_kernel<<<blocks_for(count), kBlock>>>(site_pieces.get(), input.piece_count, fixed.get(),
                                                     input.fixed_cell_count, input.level, m.pieces.get());
    QTMV_CUDA_CHECK_LAUNCH("make_pieces_kernel");
  }  // the input's copies are freed here, before the build
  trace("input to pieces", count);
  // The plan needs only the candidates' sites: the pieces', then the fixed cells' in ascending
  // order (their order's first key), from a count per site.
  std::vector<std::uint64_t> fixed_before(static_cast<std::size_t>(input.site_count) + 1, 0);
  for (std::size_t k = 0; k < input.fixed_cell_count; ++k) ++fixed_before[input.fixed_cells[k].site + 1];
  for (std::size_t s = 1; s < fixed_before.size(); ++s) fixed_before[s] += fixed_before[s - 1];
  const GroupPlan plan = plan_groups(
      static_cast<std::int64_t>(count),
      [&](std::int64_t k) {
        if (k < static_cast<std::int64_t>(input.piece_count)) return input.pieces[k].site;
        const auto f = static_cast<std::uint64_t>(k - static_cast<std::int64_t>(input.piece_count));
        return static_cast<std::int32_t>(std::upper_bound(fixed_before.begin(), fixed_before.end(), f) -
                                         fixed_before.begin() - 1);
      },
      host_threads(threads));
  m.build_tree(plan, with_distance, cover.view(), trace);
}

Labeller::~Labeller() = default;

TreeInfo Labeller::tree_info() const { return impl_->tree_info; }

void Labeller::download_tree(DefaultInitVector<TreeNode>* nodes, DefaultInitVector<std::int32_t>* lists,
                             DefaultInitVector<JumpEntry>* jump) const {
  const Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  nodes->resize(m.tree_info.nodes);
  lists->resize(m.tree_info.list_entries);
  jump->resize(m.tree_info.jump_entries);
  if (!nodes->empty()) {
    QTMV_CUDA_CHECK(cudaMemcpy(nodes->data(), m.nodes.get(), nodes->size() * sizeof(TreeNode), cudaMemcpyDeviceToHost));
  }
  if (!lists->empty()) {
    QTMV_CUDA_CHECK(
        cudaMemcpy(lists->data(), m.lists.get(), lists->size() * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  if (!jump->empty()) {
    QTMV_CUDA_CHECK(cudaMemcpy(jump->data(), m.jump.get(), jump->size() * sizeof(JumpEntry), cudaMemcpyDeviceToHost));
  }
}

void Labeller::reserve(std::uint64_t max_cells, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  m.free_outputs();
  m.injected_fault = fault_step_from_environment();  // for this run's tiles
  if (max_cells > 65536) fail_if_injected(m.injected_fault, FaultStep::reserve);  // only large tiles: the caller tiles
  const std::size_t before = m.bytes;
  m.site = device_alloc<std::int32_t>(max_cells, &m.bytes, m.injected_fault);
  // brute needs the labels of a whole tile for its boundary pass; distances on request.
  if (want_distance) m.metres = device_alloc<float>(max_cells, &m.bytes, m.injected_fault);
  if (want_boundary) {
    m.boundary = device_alloc<std::uint8_t>(max_cells, &m.bytes, m.injected_fault);
    m.pending_spans =
        device_alloc<std::uint32_t>((max_cells + kPaintSpan - 1) / kPaintSpan, &m.bytes, m.injected_fault);
  }
  m.counters = device_alloc<unsigned int>(2, &m.bytes, m.injected_fault);
  m.output_bytes = m.bytes - before;
  m.capacity = max_cells;
}

float Labeller::run(grid::Code first, std::uint64_t count, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  if (count > m.capacity) throw std::invalid_argument("Labeller::run: more cells than reserved");
  if ((want_distance && !m.metres) || (want_boundary && !m.boundary)) {
    throw std::invalid_argument("Labeller::run: outputs asked for that reserve() did not make room for");
  }
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  if (first > 0) fail_if_injected(m.injected_fault, FaultStep::run);  // after the first tile: a failure mid-run
  float* metres = want_distance ? m.metres.get() : nullptr;
  std::uint8_t* boundary = want_boundary ? m.boundary.get() : nullptr;
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (m.hier) {
    const TreeView view = m.view();
    if (count == 0) {
      // nothing to label
    } else if (metres || count < kPaintMinCells) {
      // With distances the tree has no uniform leaves: cell by cell. So too for few cells, which
      // would give the paint kernel too few warps to hide its latency.
      tree_label_kernel<<<blocks_for(count), kBlock>>>(view, first, count, m.site.get(), metres, boundary);
      QTMV_CUDA_CHECK_LAUNCH("tree_label_kernel");
    } else {
      // Labels, flags 0 inside uniform leaves and pending elsewhere; then the pending flags.
      const std::uint64_t spans = (count + kPaintSpan - 1) / kPaintSpan;
      if (spans > 0xffffffffu - m.paint_blocks * kPaintWarps) {
        throw std::invalid_argument("Labeller::run: too many cells for one launch");
      }
      QTMV_CUDA_CHECK(cudaMemsetAsync(m.counters.get(), 0, 2 * sizeof(unsigned int)));
      const std::uint64_t blocks = (spans + kPaintWarps - 1) / kPaintWarps;
      tree_paint_kernel<<<static_cast<unsigned int>(blocks < m.paint_blocks ? blocks : m.paint_blocks), kBlock>>>(
          view, m.jump_clean.get(), first, count, m.site.get(), boundary, boundary ? m.pending_spans.get() : nullptr,
          m.counters.get(), m.counters.get() + 1);
      QTMV_CUDA_CHECK_LAUNCH("tree_paint_kernel");
      if (boundary) {
        // Enough blocks to fill the device; each takes listed spans in turn.
        tree_flag_kernel<<<m.flag_blocks, kBlock>>>(view, first, count, m.site.get(), boundary, m.pending_spans.get(),
                                                    m.counters.get());
        QTMV_CUDA_CHECK_LAUNCH("tree_flag_kernel");
      }
    }
  } else {
    brute_label_kernel<<<blocks_for(count), kBlock>>>(m.pieces.get(), m.piece_count, m.level, first, count,
                                                      m.site.get(), metres);
    QTMV_CUDA_CHECK_LAUNCH("brute_label_kernel");
    if (boundary) {
      brute_boundary_kernel<<<blocks_for(count), kBlock>>>(m.pieces.get(), m.piece_count, m.level, first, count,
                                                           m.site.get(), boundary);
      QTMV_CUDA_CHECK_LAUNCH("brute_boundary_kernel");
    }
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.stop));
  QTMV_CUDA_CHECK(cudaEventSynchronize(m.stop));
  float ms = 0;
  QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, m.start, m.stop));
  return ms;
}

float Labeller::download(std::uint64_t offset, std::uint64_t count, std::int32_t* site, float* distance_m,
                         std::uint8_t* boundary) {
  Impl& m = *impl_;
  if (offset + count > m.capacity) throw std::invalid_argument("Labeller::download: outside the reserved cells");
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (site) {
    QTMV_CUDA_CHECK(cudaMemcpy(site, m.site.get() + offset, count * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  if (distance_m && m.metres) {
    QTMV_CUDA_CHECK(cudaMemcpy(distance_m, m.metres.get() + offset, count * sizeof(float), cudaMemcpyDeviceToHost));
  }
  if (boundary && m.boundary) {
    QTMV_CUDA_CHECK(cudaMemcpy(boundary, m.boundary.get() + offset, count, cudaMemcpyDeviceToHost));
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.stop));
  QTMV_CUDA_CHECK(cudaEventSynchronize(m.stop));
  float ms = 0;
  QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, m.start, m.stop));
  return ms;
}

float Labeller::select_outline(grid::Code first, std::uint64_t count, OutlineCells* out) {
  Impl& m = *impl_;
  if (count > m.capacity || !m.boundary) {
    throw std::invalid_argument("Labeller::select_outline: the last run had no flags for these cells");
  }
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  const std::uint64_t chunk = std::min<std::uint64_t>(kOutlineChunkCells, m.capacity);
  if (!m.select_index) {
    // Counted in the outputs: reserve() freed the last ones, free_outputs() frees these.
    const std::size_t before = m.bytes;
    m.select_index = device_alloc<std::uint32_t>(chunk, &m.bytes, m.injected_fault);
    m.select_cells = device_alloc<OutlineCell>(chunk, &m.bytes, m.injected_fault);
    m.select_count = device_alloc<std::uint32_t>(1, &m.bytes, m.injected_fault);
    std::size_t temp_bytes = 0;
    QTMV_CUDA_CHECK(cub::DeviceSelect::If(nullptr, temp_bytes, thrust::counting_iterator<std::uint32_t>(0),
                                          m.select_index.get(), m.select_count.get(), static_cast<std::int64_t>(chunk),
                                          OutlinePick{m.boundary.get(), first, m.level}));
    m.select_temp = device_alloc<unsigned char>(temp_bytes, &m.bytes, m.injected_fault);
    m.output_bytes += m.bytes - before;
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  // The chunks' outline cells gather in select_cells (a chunk's worth) and cross to the host in
  // as few copies as fit: small pageable copies, and the vector's growth, were most of the time.
  std::uint64_t pending = 0;
  const auto flush = [&](std::uint64_t done_cells) {
    if (pending == 0) return;
    const std::size_t at = out->size();
    if (out->capacity() < at + pending && done_cells < count) {
      // Room for the rest of the range at the rate seen so far, so that the vector grows once.
      const double rate = static_cast<double>(pending) / static_cast<double>(done_cells);
      out->reserve(at + static_cast<std::size_t>(pending + rate * 1.1 * static_cast<double>(count - done_cells)));
    }
    out->resize(at + pending);
    // Through page-locked memory in pieces, each copied on to the list on all cores.
    constexpr std::uint64_t kStagedCells = std::uint64_t{1} << 22;  // 64 MiB
    const std::uint64_t staged = std::min(pending, kStagedCells);
    auto* host = static_cast<OutlineCell*>(m.select_host.get(staged * sizeof(OutlineCell)));
    for (std::uint64_t done = 0; done < pending; done += staged) {
      const std::uint64_t n = std::min(staged, pending - done);
      QTMV_CUDA_CHECK(cudaMemcpy(host, m.select_cells.get() + done, n * sizeof(OutlineCell), cudaMemcpyDeviceToHost));
      parallel_copy(out->data() + at + done, host, n * sizeof(OutlineCell));
    }
    pending = 0;
  };
  for (std::uint64_t offset = 0; offset < count; offset += chunk) {
    const std::uint64_t n = std::min(chunk, count - offset);
    std::size_t temp_bytes = m.select_temp.size();
    QTMV_CUDA_CHECK(cub::DeviceSelect::If(m.select_temp.get(), temp_bytes,
                                          thrust::counting_iterator<std::uint32_t>(0), m.select_index.get(),
                                          m.select_count.get(), static_cast<std::int64_t>(n),
                                          OutlinePick{m.boundary.get() + offset, first + offset, m.level}));
    std::uint32_t selected = 0;
    QTMV_CUDA_CHECK(cudaMemcpy(&selected, m.select_count.get(), sizeof selected, cudaMemcpyDeviceToHost));
    if (selected == 0) continue;
    if (pending + selected > chunk) flush(offset);
    gather_outline_kernel<<<blocks_of(selected), kBlock>>>(m.select_index.get(), selected, first + offset,
                                                           m.site.get() + offset, m.boundary.get() + offset,
                                                           m.select_cells.get() + pending);
    QTMV_CUDA_CHECK_LAUNCH("gather_outline_kernel");
    pending += selected;
  }
  flush(count);
  QTMV_CUDA_CHECK(cudaEventRecord(m.stop));
  QTMV_CUDA_CHECK(cudaEventSynchronize(m.stop));
  float ms = 0;
  QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, m.start, m.stop));
  return ms;
}

std::vector<std::int32_t> Labeller::brute_sites(const std::vector<grid::Code>& codes) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  std::size_t scratch = 0;
  DeviceArray<grid::Code> device_codes = device_copy(codes, &scratch, m.injected_fault);
  DeviceArray<std::int32_t> device_sites = device_alloc<std::int32_t>(codes.size(), &scratch, m.injected_fault);
  std::vector<std::int32_t> sites(codes.size());
  if (!codes.empty()) {
    brute_codes_kernel<<<blocks_for(codes.size()), kBlock>>>(m.pieces.get(), m.piece_count, m.level, device_codes.get(),
                                                             codes.size(), device_sites.get());
    QTMV_CUDA_CHECK_LAUNCH("brute_codes_kernel");
    QTMV_CUDA_CHECK(
        cudaMemcpy(sites.data(), device_sites.get(), codes.size() * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  device_codes.free_checked();
  device_sites.free_checked();
  return sites;
}

std::size_t Labeller::device_bytes() const { return impl_->bytes; }

const std::int32_t* Labeller::device_sites() const { return impl_->site.get(); }

}  // namespace qtmv::label::cuda
