#include "label/outline_join.hpp"

#include <algorithm>
#include <cstdint>

#include "common/openmp_threads.hpp"
#include "common/radix_sort.hpp"

namespace qtmv::label {

namespace {

/// One stretch of codes [first, end) of every list: list p's cells [at[p], stop[p]).
struct Stretch {
  std::vector<std::size_t> at, stop;
};

/// Merges one stretch of the sorted lists (each code once: the first list's site, the boundary
/// flags or-ed), calling emit(cell) in code order; returns the cells emitted.
template <class Emit>
std::size_t merge_stretch(const std::vector<OutlineCells>& parts, Stretch s, const Emit& emit) {
  std::size_t emitted = 0;
  const std::size_t lists = parts.size();
  for (;;) {
    // The smallest code at the lists' heads (a few lists: one per thread of the pass).
    grid::Code lowest = ~grid::Code{0};
    std::size_t first = lists;
    for (std::size_t p = 0; p < lists; ++p) {
      if (s.at[p] < s.stop[p] && parts[p][s.at[p]].code() < lowest) {
        lowest = parts[p][s.at[p]].code();
        first = p;
      }
    }
    if (first == lists) return emitted;
    OutlineCell cell = parts[first][s.at[first]];
    for (std::size_t p = first; p < lists; ++p) {
      while (s.at[p] < s.stop[p] && parts[p][s.at[p]].code() == lowest) {
        if (parts[p][s.at[p]].boundary()) cell.mark_boundary();
        ++s.at[p];
      }
    }
    emit(cell);
    ++emitted;
  }
}

}  // namespace

OutlineCells join_outline_parts(std::vector<OutlineCells>& parts, int level, grid::CodeRange range, int threads) {
  // Each list in code order on its own (stable: a list's own repeats keep their order).
  for (OutlineCells& p : parts) radix_sort(p, grid::code_bits(level), [](const OutlineCell& c) { return c.code(); });
  // Stretches of the range, several a thread (the cells are spread unevenly over the codes),
  // each list's cells of a stretch found by binary search.
  threads = thread_count(threads);
  const std::size_t stretches = static_cast<std::size_t>(std::max(1, 8 * threads));
  const auto bound = [&](const OutlineCells& p, grid::Code code) {
    return static_cast<std::size_t>(
        std::lower_bound(p.begin(), p.end(), code, [](const OutlineCell& c, grid::Code v) { return c.code() < v; }) -
        p.begin());
  };
  std::vector<Stretch> stretch(stretches);
  for (std::size_t j = 0; j < stretches; ++j) {
    const grid::Code first = range.first + range.size() / stretches * j;
    const grid::Code end = j + 1 == stretches ? range.end : range.first + range.size() / stretches * (j + 1);
    for (const OutlineCells& p : parts) {
      stretch[j].at.push_back(bound(p, first));
      stretch[j].stop.push_back(bound(p, end));
    }
  }
  // Counted, then written in place: the result is allocated once, at its size.
  std::vector<std::size_t> start(stretches + 1, 0);
  const auto n = static_cast<std::int64_t>(stretches);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::int64_t j = 0; j < n; ++j) {
    start[static_cast<std::size_t>(j) + 1] = merge_stretch(parts, stretch[static_cast<std::size_t>(j)], [](const OutlineCell&) {});
  }
  for (std::size_t j = 0; j < stretches; ++j) start[j + 1] += start[j];
  OutlineCells all;
  all.resize(start[stretches]);  // not zeroed: every cell is written below
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::int64_t j = 0; j < n; ++j) {
    OutlineCell* out = all.data() + start[static_cast<std::size_t>(j)];
    merge_stretch(parts, stretch[static_cast<std::size_t>(j)], [&](const OutlineCell& c) { *out++ = c; });
  }
  for (OutlineCells& p : parts) OutlineCells().swap(p);
  return all;
}

}  // namespace qtmv::label
