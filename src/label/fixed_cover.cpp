#include "label/fixed_cover.hpp"

namespace qtmv::label {

FixedCover make_fixed_cover(const LabelInput& input) {
  FixedCover cover;
  cover.level = input.level;
  const std::vector<grid::KeyRange> parts = held_claims(input);
  cover.first.reserve(parts.size());
  cover.last.reserve(parts.size());
  cover.site.reserve(parts.size());
  cover.owner_run.reserve(parts.size());
  for (const grid::KeyRange& r : parts) {
    const bool same_owner = !cover.site.empty() && cover.site.back() == r.owner;
    cover.owner_run.push_back(cover.owner_run.empty() ? 0 : cover.owner_run.back() + (same_owner ? 0 : 1));
    cover.first.push_back(r.first);
    cover.last.push_back(r.last);
    cover.site.push_back(r.owner);
  }
  return cover;
}

PreparedInput prepare_input(const LabelInput& given, bool hier) {
  PreparedInput out;
  out.input = given;
  if (hier) out.cover = make_fixed_cover(given);
  if (given.fixed_node_count > 0) {
    if (hier) {
      out.cover.split_partly = true;
    } else {
      out.fixed_cells = fixed_cells_with_nodes(given);
    }
    out.input.fixed_cells = out.fixed_cells.data();
    out.input.fixed_cell_count = out.fixed_cells.size();
    out.input.fixed_nodes = nullptr;
    out.input.fixed_node_count = 0;
  }
  return out;
}

std::uint64_t fixed_node_cells(const LabelInput& input) {
  std::uint64_t n = 0;
  for (std::size_t k = 0; k < input.fixed_node_count; ++k) {
    n += std::uint64_t{1} << (2 * (input.level - input.fixed_nodes[k].level));
  }
  return n;
}

std::vector<FixedCell> fixed_cells_with_nodes(const LabelInput& input) {
  std::vector<FixedCell> out;
  out.reserve(input.fixed_cell_count + fixed_node_cells(input));
  out.assign(input.fixed_cells, input.fixed_cells + input.fixed_cell_count);
  for (std::size_t k = 0; k < input.fixed_node_count; ++k) {
    const FixedNode& node = input.fixed_nodes[k];
    const grid::Cell cell = grid::cell_of(node.code, node.level);
    const int depth = input.level - node.level;
    for (std::uint32_t r = 0; r < (1u << depth); ++r) {
      const grid::RowCodes row = grid::row_codes_below(cell, depth, r, input.level);
      for (grid::Code code = row.first; code <= row.last; ++code) out.push_back({code, node.site});
    }
  }
  return out;
}

}  // namespace qtmv::label
