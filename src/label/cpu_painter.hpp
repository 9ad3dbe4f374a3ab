// The CPU's labelling of a range of cells (OpenMP): the tree's leaves painted row run by row run,
// or every cell against every candidate; then the boundary flags from the labels. Internal to
// the labeller (label_cells calls it per tile).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "label/label_engine.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {

/// The tree's leaves by the rows of cells they cover, so that the pass over a range of a few rows
/// (a raster's strip) visits the leaves that meet those rows, not every leaf: a look at each of
/// 250 000 leaves took milliseconds, hundreds of times a raster.
class LeafRows {
 public:
  explicit LeafRows(const Tree& tree);
  /// The leaves (indices into tree.leaves) whose rows meet the rows that [first, first + count)
  /// runs through, into `out` (replaced), in ascending order.
  void meeting(grid::Code first, std::uint64_t count, std::vector<std::int64_t>& out) const;
  /// Host bytes of the index.
  std::uint64_t memory_bytes() const;

 private:
  struct Entry {
    std::uint32_t row;  ///< the leaf's row at its level
    std::int64_t leaf;
  };
  int level_ = 0;
  /// Per leaf level and octant, sorted by row.
  std::vector<Entry> entries_[grid::kMaxLevel + 1][grid::kOctants];
};

/// The hier pass over the cells [first, first + count) of tree.level: every leaf paints its
/// cells (a uniform leaf writes its site; a list leaf tests its few candidates per cell), then the
/// boundary flags come from the labels. `metres` and `boundary` may be null (not asked for).
/// `rows` (may be null: every leaf is looked at) picks the leaves that meet the range's rows.
void cpu_tree_range(const Tree& tree, const TreeView& tv, grid::Code first, std::uint64_t count,
                    std::int32_t* site, float* metres, std::uint8_t* boundary, int threads,
                    const LeafRows* rows = nullptr);

/// The hier pass that follows the outlines: the outline cells (outline_cells.hpp) of `range` (row
/// starts at both ends; the leaves outside it are skipped), in code order, from the cells of the list leaves and the rims of the uniform leaves
/// (a uniform leaf's inner cells have all three neighbours in it: no boundary, no row end).
/// Work and memory grow with the outlines, not with the cells.
/// `done` (may be empty) is called on the calling thread, outside any parallel region, with the
/// fraction of the leaves done, every 1/256 of them or so; it may throw to stop the pass.
OutlineCells cpu_tree_outlines(const Tree& tree, const TreeView& tv, int threads, grid::CodeRange range,
                               const std::function<void(double)>& done = {});

/// cpu_tree_outlines in two steps, so that the tree can be freed between them: the threads'
/// lists (in no order, codes listed more than once, some outside `range`), which
/// join_outline_parts (outline_join.hpp) makes the outline cells of `range`.
std::vector<OutlineCells> cpu_tree_outline_parts(const Tree& tree, const TreeView& tv, int threads, grid::CodeRange range,
                                                 const std::function<void(double)>& done = {});

/// The outline cells of a labelled range [first, first + count) (code order): its boundary cells
/// and row ends, appended to *out.
void append_outline_cells(int level, grid::Code first, std::uint64_t count, const std::int32_t* site,
                          const std::uint8_t* boundary, int threads, OutlineCells* out);

/// The brute-force pass over [first, first + count): each cell against every candidate.
void cpu_brute_range(const std::vector<Piece>& candidates, int level, grid::Code first, std::uint64_t count,
                     std::int32_t* site, float* metres, std::uint8_t* boundary, int threads);

}  // namespace qtmv::label
