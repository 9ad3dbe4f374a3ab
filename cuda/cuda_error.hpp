// The one wording of a failed CUDA call, for every .cu file's checks.
#pragma once

#include <cuda_runtime.h>

#include <string>

namespace qtmv::cuda_error {

/// "CUDA error NAME (DESCRIPTION) in CALL at FILE:LINE".
inline std::string describe(cudaError_t status, const char* call, const char* file, int line) {
  return std::string("CUDA error ") + cudaGetErrorName(status) + " (" + cudaGetErrorString(status) + ") in " + call +
         " at " + file + ":" + std::to_string(line);
}

}  // namespace qtmv::cuda_error
