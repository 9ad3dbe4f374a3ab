#include "sites/append_sites.hpp"

#include <algorithm>
#include <cstddef>

namespace qtmv::sites {

namespace {

/// Calls copy(k, first, last) for the positions [first, last) of part k of an array whose parts
/// start at `starts` (ascending; starts[n] its end), on all threads in slices of equal size: one
/// large part (a continent's coasts) keeps every thread busy, not one.
template <class Copy>
void copy_parts_in_slices(const std::vector<std::size_t>& starts, int threads, const Copy& copy) {
  constexpr std::size_t kSlice = std::size_t{1} << 16;
  const std::size_t begin = starts.front(), end = starts.back();
  const auto slices = static_cast<std::int64_t>((end - begin + kSlice - 1) / kSlice);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t slice = 0; slice < slices; ++slice) {
    const std::size_t first = begin + static_cast<std::size_t>(slice) * kSlice;
    const std::size_t last = std::min(end, first + kSlice);
    auto k = static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), first) - starts.begin()) - 1;
    for (; k + 1 < starts.size() && starts[k] < last; ++k) {
      const std::size_t from = std::max(first, starts[k]), to = std::min(last, starts[k + 1]);
      if (from < to) copy(k, from, to);
    }
  }
}

}  // namespace

void append_sites(SiteGeometry& out, const std::vector<SiteGeometry>& built, const std::vector<std::int32_t>& ids,
                  int threads) {
  const std::size_t n = built.size();
  if (n == 0) return;
  std::vector<std::size_t> pieces(n + 1), cells(n + 1), fixed(n + 1), nodes(n + 1);
  pieces[0] = out.pieces.size();
  cells[0] = out.site_cells.size();
  fixed[0] = out.fixed_cells.size();
  nodes[0] = out.fixed_nodes.size();
  for (std::size_t k = 0; k < n; ++k) {
    pieces[k + 1] = pieces[k] + built[k].pieces.size();
    cells[k + 1] = cells[k] + built[k].site_cells.size();
    fixed[k + 1] = fixed[k] + built[k].fixed_cells.size();
    nodes[k + 1] = nodes[k] + built[k].fixed_nodes.size();
  }
  out.pieces.resize(pieces[n]);
  out.site_cells.resize(cells[n]);
  out.fixed_cells.resize(fixed[n]);
  out.fixed_nodes.resize(nodes[n]);
  copy_parts_in_slices(pieces, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const SitePiece* in = built[k].pieces.data();
    for (std::size_t i = from; i < to; ++i) {
      out.pieces[i] = in[i - pieces[k]];
      out.pieces[i].site = ids[k];
    }
  });
  copy_parts_in_slices(cells, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const SiteCell* in = built[k].site_cells.data();
    const auto piece_offset = static_cast<std::uint32_t>(pieces[k]);
    for (std::size_t i = from; i < to; ++i) {
      SiteCell c = in[i - cells[k]];
      c.site = ids[k];
      c.piece_begin += piece_offset;
      c.piece_end += piece_offset;
      out.site_cells[i] = c;
    }
  });
  copy_parts_in_slices(fixed, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const FixedCell* in = built[k].fixed_cells.data();
    for (std::size_t i = from; i < to; ++i) out.fixed_cells[i] = {in[i - fixed[k]].code, ids[k]};
  });
  copy_parts_in_slices(nodes, threads, [&](std::size_t k, std::size_t from, std::size_t to) {
    const FixedNode* in = built[k].fixed_nodes.data();
    for (std::size_t i = from; i < to; ++i) {
      const FixedNode& node = in[i - nodes[k]];
      out.fixed_nodes[i] = {node.code, node.level, ids[k]};
    }
  });
  out.site_count = ids[n - 1] + 1;
}

}  // namespace qtmv::sites
