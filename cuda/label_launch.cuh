// The labeller's launch shapes: threads per block and grids for a count of items (the device's
// threads), and the host's threads for its share of the work.
#pragma once

#include <algorithm>
#include <cstdint>
#include <thread>

namespace qtmv::label::cuda {

/// Threads per block of every labeller kernel.
constexpr int kBlock = 256;

/// Blocks for `count` items, capped for the kernels that loop over their items (grid-stride).
inline unsigned int blocks_for(std::uint64_t count) {
  const std::uint64_t blocks = (count + kBlock - 1) / kBlock;
  return static_cast<unsigned int>(blocks < 0x7fffffffu ? blocks : 0x7fffffffu);
}

/// Blocks for `count` items, one a thread (counts that fit a grid).
inline unsigned int blocks_of(std::uint64_t count) { return static_cast<unsigned int>((count + kBlock - 1) / kBlock); }

/// Threads for the host's share of the build (the groups' plan): `asked`, or all when 0.
inline int host_threads(int asked) {
  return asked > 0 ? asked : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace qtmv::label::cuda
