// The candidates made on the device (candidates_cuda.cu): the exact rule's pieces from the
// labeller's input, as make_candidates (src/label/candidates.cpp) makes them on the host, so that
// the host neither builds nor copies the larger pieces.
#pragma once

#include <cstddef>

#include "device_memory.cuh"
#include "device_trace.cuh"
#include "label/label_input.hpp"
#include "label/label_math.hpp"

namespace qtmv::label::cuda {

/// The pieces of make_candidates(input, Rule::exact) on the current device: the input's pieces,
/// then its fixed cells' centres in quadtree order (fixed_cells_in_quadtree_order: sorted here up
/// to kMaxDeviceOrderLevel, above it on the host with `threads` as LabelOptions::threads). Their
/// bytes are added to *bytes; the input's copies are freed before this returns.
device_memory::DeviceArray<Piece> make_device_pieces(const LabelInput& input, int threads, std::size_t* bytes,
                                                     device_memory::FaultStep injected, DeviceTrace& trace);

}  // namespace qtmv::label::cuda
