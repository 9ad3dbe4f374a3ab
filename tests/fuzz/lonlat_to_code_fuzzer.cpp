// lon/lat -> code (grid::lonlat_to_code) on any doubles and level: a valid input gives a valid
// code whose cell round-trips; anything else gives kInvalidCode. Never a crash or a UB report.
#include <cstdlib>

#include "fuzz_input.hpp"
#include "grid/qtm.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace qtmv::grid;
  qtmv::fuzz::Input in(data, size);
  const double lon = in.take<double>(), lat = in.take<double>();
  const int level = in.take<std::int8_t>();
  const Code code = lonlat_to_code(lon, lat, level);
  const bool valid_input = is_valid_level(level) && lat >= -90.0 && lat <= 90.0 && std::isfinite(lon);
  if ((code == kInvalidCode) == valid_input) std::abort();
  if (valid_input && (!is_valid_code(code, level) || code_of(cell_of(code, level), level) != code)) std::abort();
  return 0;
}
