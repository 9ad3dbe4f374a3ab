// memcpy on several threads, for arrays of gigabytes: one thread copies (and first touches the
// destination's pages) at a few GB/s. std::thread rather than OpenMP, so that the CUDA side's
// files, which nvcc compiles without OpenMP, use it too.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <thread>
#include <vector>

namespace qtmv {

/// Copies `bytes` from `from` to `to` (not overlapping) in 16 MiB pieces on up to `threads` threads.
inline void parallel_copy(void* to, const void* from, std::size_t bytes, int threads) {
  constexpr std::size_t kPiece = std::size_t{16} << 20;
  const std::size_t pieces = (bytes + kPiece - 1) / kPiece;
  const std::size_t used = std::min<std::size_t>(pieces, static_cast<std::size_t>(std::max(threads, 1)));
  const auto work = [&](std::size_t t) {
    for (std::size_t k = t; k < pieces; k += used) {
      const std::size_t first = k * kPiece;
      std::memcpy(static_cast<char*>(to) + first, static_cast<const char*>(from) + first, std::min(kPiece, bytes - first));
    }
  };
  if (used <= 1) {
    if (bytes > 0) std::memcpy(to, from, bytes);
    return;
  }
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < used; ++t) pool.emplace_back(work, t);
  work(0);
  for (std::thread& th : pool) th.join();
}

}  // namespace qtmv
