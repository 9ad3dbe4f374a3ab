// The trace of the labeller's device steps (QTMV_TRACE=label, common/trace.hpp): each step's
// time and two sizes, the device synchronised before each line so that a step's time is its own.
#pragma once

#include <cuda_runtime.h>

#include <string>

#include "common/trace.hpp"
#include "device_memory.cuh"

namespace qtmv::label::cuda {

/// A Labeller constructor makes one and passes it on to the build; off (and free, no
/// synchronisation) unless the label stage is traced.
class DeviceTrace {
 public:
  /// "trace: label <step> <milliseconds> ms  <a> <b>", after the device's work so far.
  void operator()(const char* step, unsigned long long a = 0, unsigned long long b = 0) {
    if (!steps_.on()) return;
    QTMV_CUDA_CHECK(cudaDeviceSynchronize());
    steps_(step, std::to_string(a) + " " + std::to_string(b));
  }

 private:
  StepTrace steps_{TraceStage::label};
};

}  // namespace qtmv::label::cuda
