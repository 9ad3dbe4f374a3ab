// code -> centre, polygon, neighbours, parent and children at any level: every grid invariant
// of one cell (the grid tests' check_cell) holds for any valid code; invalid codes are refused.
#include <cmath>
#include <cstdlib>

#include "../grid/grid_cell_checks.hpp"
#include "fuzz_input.hpp"
#include "grid/qtm.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace qtmv::grid;
  qtmv::fuzz::Input in(data, size);
  const int level = in.take<std::uint8_t>() % (kMaxLevel + 1);
  const Code code = in.take<std::uint64_t>() % cell_count(level);
  if (test::check_cell(code, level) != 0) std::abort();
  LonLat corners[kMaxPolygonCorners];
  const int n = cell_polygon(cell_of(code, level), level, corners);
  if (n != 3 && n != 4) std::abort();
  for (int k = 0; k < n; ++k) {
    if (!(std::fabs(corners[k].lat) <= 90.0 && std::fabs(corners[k].lon) <= 180.0)) std::abort();
  }
  return 0;
}
