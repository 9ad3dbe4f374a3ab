// Reading longitudes across +-180: a vertex sequence becomes one with continuous longitudes.
#pragma once

#include <cstddef>
#include <vector>

#include "grid/qtm.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

/// A path or ring with continuous longitudes: each longitude (degrees) may lie outside
/// [-180, 180) so that every edge is the straight lon/lat segment between its ends.
struct UnwrappedPath {
  std::vector<grid::LonLat> vertices;
  /// For a closed ring: how many times its longitudes wind around the globe (last - first) / 360;
  /// 0 for an open path or an ordinary ring.
  int winding = 0;
};

/// Unwraps longitudes (degrees; latitudes in [-90, 90]). With WrapMode::automatic an edge whose
/// ends are more than 180 degrees apart in longitude is joined the short way across +-180, except:
///   - a seam edge, both ends on the meridian +-180 (Antarctica's ring in world-atlas steps from
///     +180 to -180): it runs along that meridian, so its longitude change is 0;
///   - an edge with an end at a pole: the longitude of a pole means nothing, the edge is kept flat.
/// A path with no edge across +-180 (data cut there) is read flat, unless its seam edges make it
/// a ring that winds round a pole: a ring from (-180, -60) to (180, -60) to (180, 60) to
/// (-180, 60) is a band round the globe, as GEOS reads it.
/// WrapMode::none copies the coordinates. `closed`: the sequence is a ring whose last vertex
/// repeats the first; its winding is then counted.
UnwrappedPath unwrap_longitudes(const grid::LonLat* vertices, std::size_t count, bool closed, WrapMode mode);

}  // namespace qtmv::sites
