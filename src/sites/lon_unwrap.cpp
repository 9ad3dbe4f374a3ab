#include "sites/lon_unwrap.hpp"

#include <cmath>

namespace qtmv::sites {

UnwrappedPath unwrap_longitudes(const grid::LonLat* vertices, std::size_t count, bool closed, WrapMode mode) {
  UnwrappedPath out;
  out.vertices.assign(vertices, vertices + count);
  if (mode == WrapMode::none || count < 2) return out;
  double shift = 0.0;  // multiple of 360 added to the input longitude of the current vertex
  for (std::size_t k = 1; k < count; ++k) {
    const grid::LonLat& a = vertices[k - 1];
    const grid::LonLat& b = vertices[k];
    const double step = b.lon - a.lon;
    const bool at_pole = std::fabs(a.lat) == 90.0 || std::fabs(b.lat) == 90.0;
    const bool seam = std::fabs(a.lon) == 180.0 && std::fabs(b.lon) == 180.0;
    if (at_pole) {
      // flat: the longitude of a pole means nothing
    } else if (seam) {
      shift += a.lon - b.lon;  // along the meridian: same unwrapped longitude
    } else if (std::fabs(step) > 180.0) {
      shift += step > 0 ? -360.0 * std::ceil((step - 180.0) / 360.0) : 360.0 * std::ceil((-step - 180.0) / 360.0);
    }
    out.vertices[k].lon = b.lon + shift;
  }
  if (closed) out.winding = static_cast<int>(std::lround((out.vertices.back().lon - out.vertices.front().lon) / 360.0));
  return out;
}

}  // namespace qtmv::sites
