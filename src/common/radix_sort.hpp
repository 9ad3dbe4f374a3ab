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

/// The bits that hold every value up to `max` (0 for 0): the key width for radix_sort.
constexpr int bits_for(std::uint64_t max) {
  int bits = 0;
  while (bits < 64 && (max >> bits) != 0) ++bits;
  return bits;
}

/// Sorts `items` by key_of(item), a std::uint64_t below 2^key_bits (key_bits <= 64), on all cores.
/// Stable: items of equal keys keep their order. T: default-constructible and copyable.
template <class T, class Alloc, class KeyOf>
void radix_sort(std::vector<T, Alloc>& items, int key_bits, KeyOf key_of) {
  static_assert(std::is_default_constructible_v<T> && std::is_copy_assignable_v<T>, "radix_sort copies items");
  const std::size_t n = items.size();
  // Below this a comparison sort is as fast, and the digits' tables would dominate.
  constexpr std::size_t kSmall = 1 << 9;
  if (n < kSmall || key_bits <= 0) {
    std::stable_sort(items.begin(), items.end(), [&](const T& a, const T& b) { return key_of(a) < key_of(b); });
    return;
  }
  // Digits of at most 11 bits (2048 counters a thread: they stay in the first-level cache).
  constexpr int kMaxDigitBits = 11;
  const int passes = (key_bits + kMaxDigitBits - 1) / kMaxDigitBits;
  const int digit_bits = (key_bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit_bits;
  // A thread per 16384 items at most: a parallel region costs microseconds.
  constexpr std::size_t kPerThread = 1 << 14;
  const int threads = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(thread_count(0)), n / kPerThread + 1));
  std::unique_ptr<T[]> spare(new T[n]);  // default-initialised (trivial types: not written) until the first scatter
  T* from = items.data();
  T* to = spare.get();
  std::vector<std::size_t> place(static_cast<std::size_t>(threads) * buckets);
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = pass * digit_bits;
    const std::uint64_t mask = buckets - 1;
#ifdef _OPENMP  // (the includer may be built without OpenMP: then one slice)
#pragma omp parallel num_threads(threads)
#endif
    {
      // The team OpenMP gave (at most `threads`), each thread a slice.
      const auto team = static_cast<std::size_t>(team_size());
      const auto t = static_cast<std::size_t>(thread_index());
      const std::size_t begin = n * t / team, end = n * (t + 1) / team;
      std::size_t* mine = place.data() + t * buckets;
      std::fill(mine, mine + buckets, std::size_t{0});
      for (std::size_t k = begin; k < end; ++k) ++mine[(static_cast<std::uint64_t>(key_of(from[k])) >> shift) & mask];
#ifdef _OPENMP
#pragma omp barrier
#pragma omp single
#endif
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

/// Sorts `items` by (first(item), second(item)), two unsigned keys, on all cores: by one radix key
/// where both fit 64 bits together (cell codes with site ids or piece indices do up to level 20),
/// else by comparison (then not stable).
template <class T, class Alloc, class First, class Second>
void sort_by_pair(std::vector<T, Alloc>& items, First first, Second second) {
  std::uint64_t max_first = 0, max_second = 0;
  for (const T& item : items) {
    max_first = std::max<std::uint64_t>(max_first, first(item));
    max_second = std::max<std::uint64_t>(max_second, second(item));
  }
  const int low = bits_for(max_second), width = bits_for(max_first) + low;
  if (width <= 64) {
    // low is 64 only where every first key is 0 (a shift by 64 would be undefined).
    radix_sort(items, width, [&](const T& item) {
      const auto high = static_cast<std::uint64_t>(first(item));
      return (low < 64 ? high << low : 0) | static_cast<std::uint64_t>(second(item));
    });
  } else {
    std::sort(items.begin(), items.end(), [&](const T& a, const T& b) {
      return first(a) != first(b) ? first(a) < first(b) : second(a) < second(b);
    });
  }
}

}  // namespace qtmv
