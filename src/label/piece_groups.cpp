// Host side of the line runs' groups: the preorder plan, and the bounds (OpenMP).
#include "label/piece_groups.hpp"

#include <stdexcept>

namespace qtmv::label {

namespace {

/// Appends the preorder groups of pieces [first, first + count) (count >= 2).
void plan_run(std::vector<GroupSpan>& spans, std::int32_t first, std::int32_t count) {
  const auto at = static_cast<std::int32_t>(spans.size());
  spans.push_back({first, count, 1});
  if (count > kGroupLeafPieces) {
    const std::int32_t half = count / 2;
    plan_run(spans, first, half);
    plan_run(spans, first + half, count - half);
  }
  spans[at].size = static_cast<std::int32_t>(spans.size()) - at;
}

}  // namespace

GroupPlan plan_groups(const std::vector<Piece>& pieces) {
  if (pieces.size() > 0x7fffffffu) throw std::invalid_argument("plan_groups: more than 2^31 candidates");
  GroupPlan plan;
  const auto n = static_cast<std::int32_t>(pieces.size());
  for (std::int32_t first = 0; first < n;) {
    // A run goes on while the site stays the same and, after an arc, the next piece starts at
    // its end (a new line or ring starts a new run); points of one site (fixed cells, a
    // multipoint) make one run.
    std::int32_t end = first + 1;
    while (end < n && pieces[end].site == pieces[first].site &&
           ((pieces[end - 1].flags & kPiecePoint) ? (pieces[end].flags & kPiecePoint) != 0
                                                  : same_point(pieces[end - 1].b, pieces[end].a))) {
      ++end;
    }
    if (end - first == 1) {
      plan.top_items.push_back(first);
    } else {
      plan.top_items.push_back(group_item(static_cast<std::int32_t>(plan.spans.size())));
      plan_run(plan.spans, first, end - first);
    }
    first = end;
  }
  return plan;
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
