// Sorting by an unsigned integer key of known width on all cores: least significant digit first,
// a counting pass and a scatter per digit, each thread on its own slice. For the millions of
// outline cells keyed by their codes, where a comparison sort spends most of its time comparing.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/openmp_threads.hpp"

namespace qtmv {

/// Sorts `items` by key_of(item), a std::uint64_t below 2^key_bits (key_bits <= 64), on all cores.
/// Stable: items of equal keys keep their order. Vector's allocator: any; T trivially copyable.
template <class T, class Alloc, class KeyOf>
void radix_sort(std::vector<T, Alloc>& items, int key_bits, KeyOf key_of) {
  static_assert(std::is_trivially_copyable_v<T>, "radix_sort moves items as bytes");
  const std::size_t n = items.size();
  // Below this a comparison sort is as fast, and the digits' tables would dominate.
  constexpr std::size_t kSmall = 1 << 15;
  if (n < kSmall || key_bits <= 0) {
    std::stable_sort(items.begin(), items.end(), [&](const T& a, const T& b) { return key_of(a) < key_of(b); });
    return;
  }
  // Digits of at most 11 bits (2048 counters a thread: they stay in the first-level cache).
  constexpr int kMaxDigitBits = 11;
  const int passes = (key_bits + kMaxDigitBits - 1) / kMaxDigitBits;
  const int digit_bits = (key_bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit_bits;
  const int threads = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(thread_count(0)), n / (kSmall / 4) + 1));
  std::unique_ptr<T[]> spare(new T[n]);  // uninitialised: every slot is written by the first scatter
  T* from = items.data();
  T* to = spare.get();
  std::vector<std::size_t> place(static_cast<std::size_t>(threads) * buckets);
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = pass * digit_bits;
    const std::uint64_t mask = buckets - 1;
#pragma omp parallel num_threads(threads)
    {
      // The team OpenMP gave (at most `threads`), each thread a slice.
      const auto team = static_cast<std::size_t>(team_size());
      const auto t = static_cast<std::size_t>(thread_index());
      const std::size_t begin = n * t / team, end = n * (t + 1) / team;
      std::size_t* mine = place.data() + t * buckets;
      std::fill(mine, mine + buckets, std::size_t{0});
      for (std::size_t k = begin; k < end; ++k) ++mine[(static_cast<std::uint64_t>(key_of(from[k])) >> shift) & mask];
#pragma omp barrier
#pragma omp single
      {
        // Each digit's slots, thread after thread (so that equal keys keep their order).
        std::size_t at = 0;
        for (std::size_t b = 0; b < buckets; ++b) {
          for (std::size_t u = 0; u < team; ++u) {
            const std::size_t count = place[u * buckets + b];
            place[u * buckets + b] = at;
            at += count;
          }
        }
      }
      for (std::size_t k = begin; k < end; ++k) to[mine[(static_cast<std::uint64_t>(key_of(from[k])) >> shift) & mask]++] = from[k];
    }
    std::swap(from, to);
  }
  if (from != items.data()) std::copy(from, from + n, items.data());
}

}  // namespace qtmv
