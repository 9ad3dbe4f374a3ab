// Brute force on the device (brute_force_cuda.cu), as the labeller's device API (label_cuda.cu)
// calls it: every cell against every candidate, as the CPU's brute force.
#pragma once

#include <cstdint>
#include <vector>

#include "device_memory.cuh"
#include "grid/qtm.hpp"
#include "label/label_math.hpp"

namespace qtmv::label::cuda {

/// Labels codes [first, first + count) of `level` by brute force into site (and metres, boundary
/// when not null), on the default stream, not waited for.
void label_by_brute_force(const Piece* pieces, int piece_count, int level, grid::Code first, std::uint64_t count,
                          std::int32_t* site, float* metres, std::uint8_t* boundary);

/// The float64 brute-force labels of the given codes (the reference of the benchmark's check).
std::vector<std::int32_t> brute_force_sites(const Piece* pieces, int piece_count, int level,
                                            const std::vector<grid::Code>& codes, device_memory::FaultStep injected);

}  // namespace qtmv::label::cuda
