// The labeller's sparse output port: what the vector outputs are made of, in memory that grows
// with the regions' outlines (2x per level) rather than with the cells (4x). The writers include
// this header only, not the labeller.
//
// The outline cells of a level are, in code order, every boundary cell (one of its three edge
// neighbours has another site) and every row end (column 0 or 2 row of its octant row: the
// cells along the octants' meridians, +-180 and the pole cells among them). Why that suffices:
//   - codes run row by row, and two cells next to each other in a row share an edge; a cell that
//     is not a boundary cell has its edge neighbours' site. So between two outline cells of one
//     row every cell has the site of the outline cell on its left (site_of), and a row starts with
//     an outline cell; the cells per site follow from the gaps between outline codes
//     (count_cells_per_site).
//   - an edge between two sites has a boundary cell on each side, and the regions' cuts at +-180
//     and along the poles' lines are edges of row ends: regions and Voronoi edges are traced from
//     the outline cells alone, with site_of for a neighbour's site.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/default_init_allocator.hpp"
#include "common/huge_page_allocator.hpp"
#include "common/parallel_copy.hpp"
#include "common/openmp_threads.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"

namespace qtmv::label {

/// One outline cell: its code, its site, and whether it is a boundary cell (else it is a row end
/// whose neighbours all share its site). 12 bytes in three 32-bit words (hundreds of millions of
/// them at the finer levels; the GPU writes them too, so no 64-bit member at a 4-byte offset):
/// the code's low word, its high word with the boundary flag in the top bit (a code has at most
/// 51 bits), and the site.
struct OutlineCell {
  static constexpr std::uint32_t kBoundaryBit = 0x80000000u;

  OutlineCell() = default;
  /// `boundary_cell`: non-zero for a boundary cell.
  QTMV_HD OutlineCell(grid::Code code, std::int32_t site_id, unsigned boundary_cell)
      : code_low(static_cast<std::uint32_t>(code)),
        code_high(static_cast<std::uint32_t>(code >> 32) | (boundary_cell != 0 ? kBoundaryBit : 0u)),
        site(site_id) {}
  QTMV_HD grid::Code code() const { return grid::Code{code_high & ~kBoundaryBit} << 32 | code_low; }
  /// True: a boundary cell; false: a row end only.
  QTMV_HD bool boundary() const { return (code_high & kBoundaryBit) != 0; }
  QTMV_HD void mark_boundary() { code_high |= kBoundaryBit; }

  std::uint32_t code_low;
  std::uint32_t code_high;  ///< the code's bits 32 and up; bit 31: the boundary flag
  std::int32_t site;
};
static_assert(sizeof(OutlineCell) == 12, "an outline cell is three 32-bit words");
static_assert(grid::code_bits(grid::kMaxLevel) <= 63, "a code leaves the top bit for the boundary flag");

/// True for the first and last cell of an octant row (column 0 or 2 row).
QTMV_HD inline bool is_row_end(const grid::Cell& c) { return c.col == 0 || c.col == 2 * c.row; }

/// A list of outline cells (in code order where it is a product): gigabytes at the finer levels,
/// in huge pages (fewer page faults when filled on all cores).
using OutlineCells = std::vector<OutlineCell, qtmv::HugePageAllocator<OutlineCell>>;

/// Room for `capacity` cells in *cells, its cells copied on `threads` threads when it must move:
/// vector::reserve copies gigabytes on one thread (seconds at level 16).
inline void grow_outline_cells(OutlineCells* cells, std::size_t capacity, int threads) {
  if (capacity <= cells->capacity()) return;
  OutlineCells bigger;
  bigger.reserve(capacity);
  bigger.resize(cells->size());
  qtmv::parallel_copy(bigger.data(), cells->data(), cells->size() * sizeof(OutlineCell), threads);
  cells->swap(bigger);
}

/// Outline cells for the rest of a range, `cells_left` cells, at the rate of `outline` outline
/// cells in the `cells_done` cells before them, and a tenth more: a list given that room grows
/// once, not again by a copy of all it holds.
inline std::size_t outline_room_for_rest(std::size_t outline, std::uint64_t cells_done, std::uint64_t cells_left) {
  if (cells_done == 0) return 0;
  const double rate = static_cast<double>(outline) / static_cast<double>(cells_done);
  return static_cast<std::size_t>(rate * 1.1 * static_cast<double>(cells_left));
}

/// Outline cells listed per octant row: 2 per row but the pole row's one, 8 octants.
inline std::uint64_t row_end_count(int level) { return 8 * (2 * grid::rows_per_octant(level) - 1); }

/// Outline cells of the octant rows that start in [first, end): row_end_count(level) for the
/// whole level. `first` and `end` are row starts (qtm_code_ranges.hpp).
inline std::uint64_t row_end_count(int level, grid::CodeRange range) {
  std::uint64_t count = 0;
  for (grid::Code code = range.first; code < range.end;) {
    const grid::Cell c = grid::cell_of(code, level);
    count += c.row == 0 ? 1 : 2;
    code += 2 * std::uint64_t{c.row} + 1;
  }
  return count;
}

/// The sparse outputs of one labelled level, or of one range of it that starts and ends at row
/// starts (a tile; grid/qtm_code_ranges.hpp): the products of a level's ranges, concatenated in
/// code order (cells) and added up (cells_per_site), are those of the whole level.
struct Outlines {
  int level = 0;
  std::int32_t site_count = 0;
  grid::CodeRange range;                      ///< the codes labelled (whole_level(level) for a whole run)
  OutlineCells cells;             ///< every outline cell of the range, in code order, once
  std::vector<std::uint64_t> cells_per_site;  ///< cells of the range labelled with each site (site_count)
};

/// The site of any cell of the level: the site of the last outline cell at or before `code`
/// (the row's first cell is one; the cells after it in the row up to the next share its site).
inline std::int32_t site_of(const OutlineCells& cells, grid::Code code) {
  const auto after = std::upper_bound(cells.begin(), cells.end(), code,
                                      [](grid::Code c, const OutlineCell& o) { return c < o.code(); });
  if (after == cells.begin()) throw std::logic_error("outline cells: no row start at or before code " + std::to_string(code));
  return (after - 1)->site;
}

/// The index of the last outline cell at or before `code`, searched forwards from index `lo`
/// (cells[lo].code <= code): galloping, so that the cost grows with the log of the distance.
inline std::size_t last_at_or_before(const OutlineCells& cells, std::size_t lo, grid::Code code) {
  const std::size_t n = cells.size();
  // A few cells on first, one by one: a walk in code order mostly finds its answer there, without
  // the mispredicted branches of a binary search.
  for (int near = 0; near < 4; ++near, ++lo) {
    if (lo + 1 == n || cells[lo + 1].code() > code) return lo;
  }
  std::size_t step = 1, hi = lo + 1;
  while (hi < n && cells[hi].code() <= code) {
    lo = hi;
    step *= 2;
    hi = std::min(n, hi + step);
  }
  // cells[lo].code() <= code < cells[hi].code() (or hi == n).
  const auto after = std::upper_bound(cells.begin() + static_cast<std::ptrdiff_t>(lo), cells.begin() + static_cast<std::ptrdiff_t>(hi), code,
                                      [](grid::Code c, const OutlineCell& o) { return c < o.code(); });
  return static_cast<std::size_t>(after - cells.begin()) - 1;
}

/// The index behind site_of_near.
inline std::size_t index_near(const OutlineCells& cells, std::size_t k, grid::Code code) {
  if (code >= cells[k].code()) return last_at_or_before(cells, k, code);
  if (k > 0 && cells[k - 1].code() <= code) return k - 1;
  std::size_t step = 2, lo = k >= step ? k - step : 0;
  while (lo > 0 && cells[lo].code() > code) {
    step *= 2;
    lo = lo >= step ? lo - step : 0;
  }
  if (cells[lo].code() > code) throw std::logic_error("outline cells: no row start at or before code " + std::to_string(code));
  return last_at_or_before(cells, lo, code);
}

/// site_of for a cell near the k-th outline cell, such as one of its neighbours: the cells next to
/// it in its row are settled by the outline cells next to it in the list; others (the cell above
/// or below, a row away) by a search that gallops out from k, so that it stays in memory near k.
inline std::int32_t site_of_near(const OutlineCells& cells, std::size_t k, grid::Code code) {
  return cells[index_near(cells, k, code)].site;
}

/// site_of_near for one thread that asks about the outline cells in code order: the cells a row
/// above them, and those a row below, then come in code order too, so each search starts where
/// the last one of its kind ended (a few cells on) rather than a row away at k.
class NearSearch {
 public:
  std::int32_t site(const OutlineCells& cells, std::size_t k, grid::Code code) {
    const bool before = code < cells[k].code();
    std::size_t& last = before ? above_ : below_;
    // A last answer at or before `code` is a start; one of the cells below left behind k (a thread
    // that moved on) is not: the search from k is shorter.
    const bool usable = last < cells.size() && cells[last].code() <= code && (before || last >= k);
    last = usable ? last_at_or_before(cells, last, code) : index_near(cells, k, code);
    return cells[last].site;
  }

 private:
  static constexpr std::size_t kNone = ~std::size_t{0};
  std::size_t above_ = kNone, below_ = kNone;
};

/// The cells per site from the outline cells (in code order, row ends included) of a range that
/// ends at `end` (0: the level's end): each outline cell's site owns the cells from it up to the
/// next outline cell.
inline std::vector<std::uint64_t> count_cells_per_site(const OutlineCells& cells, int level,
                                                       std::int32_t site_count, grid::Code end = 0) {
  std::vector<std::uint64_t> count(static_cast<std::size_t>(site_count), 0);
  if (end == 0) end = grid::cell_count(level);
  const std::int64_t n = static_cast<std::int64_t>(cells.size());
  // Sums of integers: the same in any order. On all cores: hundreds of millions of cells at level 16.
  // A run of cells of one site (a row's boundary cells on one side of an edge) is added at once,
  // and a site's count, a cache miss (the sites come in no spatial order), is fetched ahead.
#pragma omp parallel num_threads(thread_count(0))
  {
    std::int32_t run_site = -1;
    std::uint64_t run_cells = 0;
    const auto add_run = [&] {
      if (run_site < 0) return;
      std::uint64_t& site_cells = count[static_cast<std::size_t>(run_site)];
#pragma omp atomic
      site_cells += run_cells;
    };
#pragma omp for schedule(static)
    for (std::int64_t k = 0; k < n; ++k) {
      constexpr std::int64_t kAhead = 16;
      if (k + kAhead < n) __builtin_prefetch(&count[static_cast<std::size_t>(cells[static_cast<std::size_t>(k + kAhead)].site)], 1);
      const OutlineCell& cell = cells[static_cast<std::size_t>(k)];
      const grid::Code next = k + 1 < n ? cells[static_cast<std::size_t>(k + 1)].code() : end;
      if (cell.site != run_site) {
        add_run();
        run_site = cell.site;
        run_cells = 0;
      }
      run_cells += next - cell.code();
    }
    add_run();
  }
  return count;
}

/// Checks what a producer promises (code order, unique codes in the range, site ids in range,
/// every row end present, the counts adding up to the range's cells); throws std::logic_error
/// naming the first fault. O(outline cells + rows of the range).
inline void check_outlines(const Outlines& o) {
  const auto fail = [](const std::string& what) { throw std::logic_error("outline cells: " + what); };
  if (static_cast<std::int32_t>(o.cells_per_site.size()) != o.site_count) fail("cells_per_site has the wrong size");
  if (!grid::is_valid_level(o.level) || !grid::is_rows(o.range, o.level)) {
    fail("the range [" + std::to_string(o.range.first) + ", " + std::to_string(o.range.end) +
         ") is not rows of the level");
  }
  // On all cores (a hundred million cells at the finer levels); the first broken cell is then
  // named, whatever the threads.
  const auto n = static_cast<std::int64_t>(o.cells.size());
  const auto broken = [&](std::int64_t k) {
    const OutlineCell& c = o.cells[static_cast<std::size_t>(k)];
    return c.code() < o.range.first || c.code() >= o.range.end || (k > 0 && o.cells[static_cast<std::size_t>(k - 1)].code() >= c.code()) ||
           c.site < 0 || c.site >= o.site_count;
  };
  std::uint64_t row_ends = 0;
  std::int64_t first_broken = n;
#pragma omp parallel num_threads(thread_count(0)) reduction(+ : row_ends) reduction(min : first_broken)
  {
    // Each thread walks its cells' rows: a cell's row decoded once per row, not once per cell
    // (the square root of cell_of, hundreds of millions of times at level 16).
    grid::Code row_first = 1, row_last = 0;  // the row of the last cell seen: none yet
#pragma omp for schedule(static)
    for (std::int64_t k = 0; k < n; ++k) {
      if (broken(k)) {
        first_broken = std::min(first_broken, k);
        continue;
      }
      const grid::Code code = o.cells[static_cast<std::size_t>(k)].code();
      if (code < row_first || code > row_last) {
        const grid::Cell c = grid::cell_of(code, o.level);
        row_first = code - c.col;
        row_last = row_first + 2 * std::uint64_t{c.row};
      }
      row_ends += code == row_first || code == row_last ? 1 : 0;
    }
  }
  if (first_broken < n) {
    const std::int64_t k = first_broken;
    const OutlineCell& c = o.cells[static_cast<std::size_t>(k)];
    if (c.code() < o.range.first || c.code() >= o.range.end) fail("code " + std::to_string(c.code()) + " is not of the range");
    if (c.site < 0 || c.site >= o.site_count) fail("site " + std::to_string(c.site) + " out of range");
    fail("codes not in increasing order at " + std::to_string(c.code()));
  }
  if (row_ends != row_end_count(o.level, o.range)) fail("row ends missing");
  std::uint64_t total = 0;
  for (const std::uint64_t n : o.cells_per_site) total += n;
  if (total != o.range.size()) fail("cells per site do not add up to the range's cells");
}

/// The outline cells of dense arrays (every cell's site, and optionally its boundary flag; without
/// flags they are computed from the sites): for the tests, and for callers that hold dense labels.
inline Outlines outlines_of_dense(int level, const std::int32_t* site, const std::uint8_t* boundary,
                                  std::int32_t site_count) {
  Outlines o;
  o.level = level;
  o.site_count = site_count;
  o.range = grid::whole_level(level);
  const grid::Code n = grid::cell_count(level);
  grid::Cell c{0, 0, 0};
  for (grid::Code code = 0; code < n; ++code, grid::next_in_code_order(c, level)) {
    if (site[code] < 0 || site[code] >= site_count) {
      throw std::invalid_argument("label " + std::to_string(site[code]) + " of cell " + std::to_string(code) +
                                  " is not a site id (0 to " + std::to_string(site_count - 1) + ")");
    }
    bool flag;
    if (boundary) {
      flag = boundary[code] != 0;
    } else {
      grid::Code nb[3];
      grid::neighbours(code, level, nb);
      flag = site[nb[0]] != site[code] || site[nb[1]] != site[code] || site[nb[2]] != site[code];
    }
    if (flag || is_row_end(c)) o.cells.push_back({code, site[code], flag});
  }
  o.cells_per_site = count_cells_per_site(o.cells, level, site_count);
  return o;
}

}  // namespace qtmv::label
