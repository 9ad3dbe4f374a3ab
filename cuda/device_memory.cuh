// Device memory of every CUDA back end (the labeller's .cu files, the edge solver's): the checks
// of CUDA calls, the RAII arrays (DeviceArray on the device, PinnedBuffer page-locked on the
// host), the device's default memory pool, allocation with give-back-and-retry, and the tests'
// fault hook (QTMV_FAULT_CUDA_OOM). Header-only (inline), so that each library that includes it
// needs no other object and no relocatable device code.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <stdexcept>
#include <utility>
#include <vector>

#include "common/config_option.hpp"
#include "common/device_out_of_memory.hpp"

namespace qtmv::device_memory {

/// "CUDA error NAME (DESCRIPTION) in CALL at FILE:LINE": the one wording of a failed CUDA call.
inline std::string describe(cudaError_t status, const char* call, const char* file, int line) {
  return std::string("CUDA error ") + cudaGetErrorName(status) + " (" + cudaGetErrorString(status) + ") in " + call +
         " at " + file + ":" + std::to_string(line);
}

/// Throws std::runtime_error naming the failed call and its place in the source;
/// DeviceOutOfMemory for a failed allocation (not sticky: the context stays usable).
inline void check(cudaError_t status, const char* call, const char* file, int line) {
  if (status == cudaSuccess) return;
  const std::string what = describe(status, call, file, line);
  if (status == cudaErrorMemoryAllocation) {
    (void)cudaGetLastError();  // or the next launch check would report it again
    throw DeviceOutOfMemory(what);
  }
  throw std::runtime_error(what);
}

#define QTMV_CUDA_CHECK(call) ::qtmv::device_memory::check((call), #call, __FILE__, __LINE__)
/// After a kernel launch: launch errors now, execution errors at the next synchronisation.
#define QTMV_CUDA_CHECK_LAUNCH(name) \
  ::qtmv::device_memory::check(cudaGetLastError(), "launch of " name, __FILE__, __LINE__)

/// Fault injection, for the tests: the switch QTMV_FAULT_CUDA_OOM (fault_switch) names a step of
/// the labeller that then fails as a device out of memory would (DeviceOutOfMemory, "injected
/// by ..."):
///   build     the device tree build (the caller labels on the CPU instead);
///   reserve   reserve() of outputs for more than 65536 cells (the caller tries smaller tiles);
///   run       run() of any tile but the first (a failure mid-run: the rest goes to the CPU);
///   allocate  a device allocation's first try, while the memory pool holds idle memory (which
///             is then given back, and the allocation tried again).
/// The switch is read when a Labeller is made and again at each reserve() (the start of a run's
/// tiles; the tests set it between construction and reserve), not at every allocation and tile.
enum class FaultStep { none, build, reserve, run, allocate };

inline const char* fault_step_name(FaultStep step) {
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
inline FaultStep injected_fault_step() {
  const std::string fault = fault_switch("QTMV_FAULT_CUDA_OOM");
  if (fault.empty()) return FaultStep::none;
  for (const FaultStep step : {FaultStep::build, FaultStep::reserve, FaultStep::run, FaultStep::allocate}) {
    if (fault == fault_step_name(step)) return step;
  }
  return FaultStep::none;
}

/// Throws DeviceOutOfMemory when `injected` (the fault QTMV_FAULT_CUDA_OOM names) is `step`.
inline void fail_if_injected(FaultStep injected, FaultStep step) {
  if (injected == step) {
    throw DeviceOutOfMemory(std::string("CUDA error cudaErrorMemoryAllocation (injected by QTMV_FAULT_CUDA_OOM=") +
                            fault_step_name(step) + ")");
  }
}

// The tree build's scratch comes from the device's default memory pool, which keeps it mapped
// after the build (mapping GBs anew costs tens of milliseconds per build at level 15). That
// memory counts as free (pool_idle_bytes), and an allocation that fails gives it back to the
// system and tries once more (allocate).

/// Bytes the current device's default pool holds but does not use.
inline std::size_t pool_idle_bytes(int device) {
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
inline cudaError_t release_pool(int device) {
  cudaMemPool_t pool;
  cudaError_t status = cudaDeviceGetDefaultMemPool(&pool, device);
  if (status == cudaSuccess) status = cudaDeviceSynchronize();
  if (status == cudaSuccess) status = cudaMemPoolTrimTo(pool, 0);
  return status;
}

/// cudaMalloc, once more after the pool's idle memory went back to the system: the one way
/// plain device memory is allocated (DeviceArray::plain).
/// (injected FaultStep::allocate: the first try fails whenever the pool holds idle memory.)
inline cudaError_t allocate(void** pointer, std::size_t bytes, FaultStep injected_fault) {
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

// --- device arrays ------------------------------------------------------------------------
//
// Every device array is a DeviceArray, allocated one of two ways, and freed the same way:
//  - plain: cudaMalloc through allocate() (out of memory: the pool's idle memory goes back to the
//    system and the allocation is tried once more). The arrays a Labeller keeps (candidates,
//    tree, outputs), the constructors' scratch, the edge solver's lanes.
//  - pool: cudaMallocAsync from the device's default pool, on the default stream. The tree
//    build's scratch (PoolBuffer), which grows level by level: the pool keeps that memory mapped
//    for the next build, where cudaMalloc and cudaFree would map and unmap it each time.

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
  /// Frees the array now, checked: DeviceOutOfMemory or std::runtime_error as any CUDA call.
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
struct PoolBuffer {
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

// --- page-locked host memory --------------------------------------------------------------

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

}  // namespace qtmv::device_memory
