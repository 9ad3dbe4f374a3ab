// The CPU outline pass's per-thread lists of outline cells made one list in code order, in memory
// that follows the result: each list sorted on its own, then all merged range by range on all
// cores, where one sort of them all would hold every listed cell twice (the sort's spare copy).
#pragma once

#include <vector>

#include "grid/qtm_code_ranges.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {

/// The outline cells of `parts` (lists of outline cells of `level` in any order; a code may be
/// listed several times, in one list or several) with codes in `range`, in code order, each code
/// once: with the site of its first listing (lists in order, each in its order) and a boundary
/// cell if any listing says so. The same list whatever the threads. `parts` are emptied (their
/// memory freed) as they are used. Holds the lists, one sort's spare copy of the longest list,
/// and the result.
OutlineCells join_outline_parts(std::vector<OutlineCells>& parts, int level, grid::CodeRange range, int threads);

}  // namespace qtmv::label
