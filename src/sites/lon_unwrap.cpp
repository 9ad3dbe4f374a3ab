#include "sites/lon_unwrap.hpp"

#include <cmath>

namespace qtmv::sites {
namespace {

bool at_pole(const grid::LonLat& p) { return std::fabs(p.lat) == 90.0; }

/// Both ends on the meridian +-180.
bool seam_edge(const grid::LonLat& a, const grid::LonLat& b) {
  return std::fabs(a.lon) == 180.0 && std::fabs(b.lon) == 180.0;
}

/// An edge that really crosses +-180 in uncut data: more than 180 degrees long in longitude,
/// neither a seam edge nor an edge to a pole.
bool crosses_antimeridian(const grid::LonLat& a, const grid::LonLat& b) {
  return std::fabs(b.lon - a.lon) > 180.0 && !seam_edge(a, b) && !at_pole(a) && !at_pole(b);
}

}  // namespace

UnwrappedPath unwrap_longitudes(const grid::LonLat* vertices, std::size_t count, bool closed, WrapMode mode) {
  UnwrappedPath out;
  out.vertices.assign(vertices, vertices + count);
  if (mode == WrapMode::none || count < 2) return out;
  bool uncut = false;
  double shift = 0.0;  // multiple of 360 added to the input longitude of the current vertex
  for (std::size_t k = 1; k < count; ++k) {
    const grid::LonLat& a = vertices[k - 1];
    const grid::LonLat& b = vertices[k];
    const double step = b.lon - a.lon;
    if (at_pole(a) || at_pole(b)) {
      // flat: the longitude of a pole means nothing
    } else if (seam_edge(a, b)) {
      shift += a.lon - b.lon;  // along the meridian: same unwrapped longitude
    } else if (std::fabs(step) > 180.0) {
      uncut = uncut || crosses_antimeridian(a, b);
      shift += step > 0 ? -360.0 * std::ceil((step - 180.0) / 360.0) : 360.0 * std::ceil((-step - 180.0) / 360.0);
    }
    out.vertices[k].lon = b.lon + shift;
  }
  if (closed) out.winding = static_cast<int>(std::lround((out.vertices.back().lon - out.vertices.front().lon) / 360.0));
  // With no edge across +-180 the data is cut there (or never reaches it), and an edge from -180
  // to +180 along a parallel is part of the shape (a band round the globe), not a seam: read
  // such a path flat, unless the seams make a ring wind round a pole (world-atlas's Antarctica).
  if (!uncut && out.winding == 0) out.vertices.assign(vertices, vertices + count);
  return out;
}

}  // namespace qtmv::sites
