// The exact and cell rules' candidates as kernel pieces, the float64 reference, and the fixed
// cells' quadtree order.
#include <algorithm>
#include <vector>

#include "label/fixed_cover.hpp"
#include "label/label_engine.hpp"
#include "common/openmp_threads.hpp"

#ifdef _OPENMP
#include <parallel/algorithm>
#endif

namespace qtmv::label {

std::vector<Piece> make_candidates(const LabelInput& given, Rule rule, int threads_requested) {
  const int threads = thread_count(threads_requested);
  // The cells of fixed nodes are fixed cells here (the reference's view of the input).
  LabelInput in = given;
  std::vector<FixedCell> with_nodes;
  if (given.fixed_node_count > 0) {
    with_nodes = fixed_cells_with_nodes(given);
    in.fixed_cells = with_nodes.data();
    in.fixed_cell_count = with_nodes.size();
    in.fixed_nodes = nullptr;
    in.fixed_node_count = 0;
  }
  std::vector<Piece> out;
  if (rule == Rule::exact) {
    out.reserve(in.piece_count + in.fixed_cell_count);
    out.resize(in.piece_count);
    const auto n = static_cast<std::int64_t>(in.piece_count);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::int64_t k = 0; k < n; ++k) {
      out[k] = candidate_of(in.pieces[k]);
    }
  } else {
    // One point per distinct (cell, site): duplicates change nothing but the work.
    std::vector<std::pair<grid::Code, std::int32_t>> cells;
    cells.reserve(in.site_cell_count);
    for (std::size_t k = 0; k < in.site_cell_count; ++k) cells.emplace_back(in.site_cells[k].code, in.site_cells[k].site);
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    out.reserve(cells.size() + in.fixed_cell_count);
    for (const auto& [code, site] : cells) out.push_back(make_point_piece(grid::cell_centre_vector(code, in.level), site));
  }
  // Fixed cells in both rules: a point at the cell's centre that wins that cell at distance 0.
  // Under the exact rule it is a point of the polygon site, so it never brings the site nearer
  // than its own geometry would. In quadtree order, as the device build makes them.
  std::vector<FixedCell> ordered;
  const FixedCell* fixed = fixed_cells_in_quadtree_order(in, threads, &ordered);
  for (std::size_t k = 0; k < in.fixed_cell_count; ++k) out.push_back(candidate_of(fixed[k], in.level));
  return out;
}

Best reference_best(const std::vector<Piece>& candidates, grid::Code code, int level) {
  const Vec3 x = grid::cell_centre_vector(code, level);
  Best best = no_best();
  consider_all(best, x, candidates.data(), static_cast<std::int64_t>(candidates.size()));
  return best;
}

// The candidates' groups halve runs of consecutive candidates of one site (piece_groups.hpp): in
// quadtree order a group of a site's fixed cells is a compact patch, nearly a quadtree node, where
// in rows it was a stretch of rows; near coasts the tree's lists stay short (110m countries, level
// 10: 12 M list entries at the labelling level instead of 238 M).
const FixedCell* fixed_cells_in_quadtree_order(const LabelInput& in, int threads_requested,
                                               std::vector<FixedCell>* storage) {
  const int threads = thread_count(threads_requested);
  struct Keyed {
    std::int32_t site;
    std::uint32_t index;
    std::uint64_t key;
  };
  auto before = [](const Keyed& a, const Keyed& b) {
    return a.site != b.site ? a.site < b.site : a.key != b.key ? a.key < b.key : a.index < b.index;
  };
  const std::int64_t n = static_cast<std::int64_t>(in.fixed_cell_count);
  if (n < 2 || in.fixed_cell_count > 0xffffffffu) return in.fixed_cells;
  std::vector<Keyed> keyed(in.fixed_cell_count);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) {
    const FixedCell& f = in.fixed_cells[k];
    keyed[k] = {f.site, static_cast<std::uint32_t>(k), grid::quadtree_key(grid::cell_of(f.code, in.level), in.level)};
  }
  std::int64_t out_of_order = 0;
#pragma omp parallel for schedule(static) num_threads(threads) reduction(+ : out_of_order)
  for (std::int64_t k = 1; k < n; ++k) out_of_order += before(keyed[k], keyed[k - 1]) ? 1 : 0;
  if (out_of_order == 0) return in.fixed_cells;
#ifdef _OPENMP
  __gnu_parallel::sort(keyed.begin(), keyed.end(), before, __gnu_parallel::default_parallel_tag(threads));
#else
  std::sort(keyed.begin(), keyed.end(), before);
#endif
  storage->resize(keyed.size());
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) (*storage)[k] = in.fixed_cells[keyed[k].index];
  return storage->data();
}

}  // namespace qtmv::label
