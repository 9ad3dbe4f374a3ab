// Host side of the line runs' groups: the preorder plan, and the bounds (OpenMP).
#include "label/piece_groups.hpp"

#include <algorithm>
#include <stdexcept>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace qtmv::label {

namespace {

/// Groups of a run of `count` pieces (0 for a single piece).
std::int32_t groups_of_run(std::int32_t count) {
  if (count <= 1) return 0;
  if (count <= kGroupLeafPieces) return 1;
  return 1 + groups_of_run(count / 2) + groups_of_run(count - count / 2);
}

/// Writes the preorder groups of pieces [first, first + count) (count >= 2) from spans[at];
/// returns the index after them.
std::int32_t plan_run(GroupSpan* spans, std::int32_t at, std::int32_t first, std::int32_t count) {
  std::int32_t next = at + 1;
  if (count > kGroupLeafPieces) {
    const std::int32_t half = count / 2;
    next = plan_run(spans, next, first, half);
    next = plan_run(spans, next, first + half, count - half);
  }
  spans[at] = {first, count, next - at};
  return next;
}

}  // namespace

GroupPlan plan_groups(std::int64_t count, const std::function<std::int32_t(std::int64_t)>& site_of, int threads) {
  if (count > 0x7fffffff) throw std::invalid_argument("plan_groups: more than 2^31 candidates");
  threads = std::max(1, threads);
  // Where runs start, found in parallel chunks and joined in order.
  std::vector<std::vector<std::int32_t>> starts(threads);
#pragma omp parallel num_threads(threads)
  {
#ifdef _OPENMP
    const int t = omp_get_thread_num(), nt = omp_get_num_threads();
#else
    const int t = 0, nt = 1;
#endif
    const std::int64_t begin = count * t / nt, end = count * (t + 1) / nt;
    std::int32_t previous = begin > 0 ? site_of(begin - 1) : -1;
    for (std::int64_t k = begin; k < end; ++k) {
      const std::int32_t site = site_of(k);
      if (k == 0 || site != previous) starts[t].push_back(static_cast<std::int32_t>(k));
      previous = site;
    }
  }
  std::vector<std::int32_t> run_first;
  for (const auto& part : starts) run_first.insert(run_first.end(), part.begin(), part.end());
  const auto runs = static_cast<std::int64_t>(run_first.size());
  run_first.push_back(static_cast<std::int32_t>(count));
  // Each run's groups, their offsets, then the spans, run by run in parallel.
  std::vector<std::int64_t> offset(runs + 1, 0);
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
  for (std::int64_t r = 0; r < runs; ++r) offset[r + 1] = groups_of_run(run_first[r + 1] - run_first[r]);
  for (std::int64_t r = 0; r < runs; ++r) offset[r + 1] += offset[r];
  if (offset[runs] > 0x7fffffff) throw std::invalid_argument("plan_groups: more than 2^31 groups");
  GroupPlan plan;
  plan.spans.resize(offset[runs]);
  plan.top_items.resize(runs);
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
  for (std::int64_t r = 0; r < runs; ++r) {
    const std::int32_t first = run_first[r], length = run_first[r + 1] - first;
    if (length == 1) {
      plan.top_items[r] = first;
    } else {
      plan.top_items[r] = group_item(static_cast<std::int32_t>(offset[r]));
      plan_run(plan.spans.data(), static_cast<std::int32_t>(offset[r]), first, length);
    }
  }
  return plan;
}

GroupPlan plan_groups(const std::vector<Piece>& pieces, int threads) {
  return plan_groups(
      static_cast<std::int64_t>(pieces.size()), [&](std::int64_t k) { return pieces[k].site; }, threads);
}

std::vector<PieceGroup> make_groups(const std::vector<Piece>& pieces, const std::vector<GroupSpan>& spans,
                                    int threads) {
  std::vector<PieceGroup> groups(spans.size());
  const auto n = static_cast<std::int64_t>(spans.size());
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads > 0 ? threads : 1)
  for (std::int64_t g = 0; g < n; ++g) groups[g] = make_group(pieces.data(), spans[g]);
  return groups;
}

}  // namespace qtmv::label
