// The one error every CUDA back end (cuda/device_memory.cuh) throws for a failed device
// allocation, so that a caller may retry with less (smaller tiles) or go on on the CPU. Plain C++:
// the host code catches it without CUDA's headers.
#pragma once

#include <stdexcept>

namespace qtmv {

/// A device allocation failed (cudaErrorMemoryAllocation, or a fault the tests inject); the
/// device's context stays usable.
class DeviceOutOfMemory : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace qtmv
