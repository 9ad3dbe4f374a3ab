// Reading longitudes across +-180: a vertex sequence becomes one with continuous longitudes.
//
// Two kinds of data meet at +-180. Cut data (Natural Earth's shapefiles, ogr2ogr -wrapdateline,
// RFC 7946 GeoJSON) stops there and is meant as written in flat lon/lat: an edge from (-180, 86)
// to (180, 86) is the whole parallel, one from (180, 90) to (-180, 90) runs along the pole.
// Uncut data (world-atlas's TopoJSON) steps across it: (-180, -16.56) to (179.36, -16.8) is a
// short edge of Fiji, and (180, -84.71) to (-180, -84.71) closes Antarctica's ring round the pole.
// unwrap_longitudes tells them apart ring by ring (the rule is stated there and in the man page).
#pragma once

#include <cstddef>
#include <cstdint>
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
  /// One flag per edge (edge k joins vertices k and k + 1): 1 where the edge runs along a parallel
  /// or a pole line as its coordinates say, so that it is traced straight in lon/lat even when
  /// edges are geodesics (a geodesic between (-180, 86) and (180, 86) would be a point).
  std::vector<std::uint8_t> straight;
  /// Edges that -wrap auto joined the short way across +-180 (real jumps, and seam edges read
  /// as zero length): what the reading changed, for the user's warning.
  std::size_t short_way_edges = 0;
};

/// Unwraps longitudes (degrees; latitudes in [-90, 90]). Edges are classified by their ends:
///   - a polar edge has an end at a pole (|lat| = 90): the longitude of a pole means nothing, so
///     it is always taken as written (along the pole line when both ends are at the pole);
///   - a seam edge joins +-180 to -+180 (both ends exactly on the meridian, opposite signs);
///   - a jump is any other edge more than 180 degrees of longitude long;
///   - the rest are ordinary edges.
/// With WrapMode::automatic a path is read as written (flat lon/lat, seam edges along their
/// parallel, or diagonal, as the coordinates say): that is data cut at +-180, which reaches its
/// seam edges along the meridian +-180 or from a pole (caps, bands round the globe, Natural
/// Earth's Antarctica). A path is uncut data instead, read with jumps joined the short way across
/// +-180 and seam edges of zero length, when
///   - it has a jump (world-atlas's Fiji and Russia step across +-180), or
///   - it has a seam edge between two edges that neither run along +-180 nor reach a pole: a
///     step across +-180 written with a vertex on each side (world-atlas's Antarctica, whose
///     coast goes round the globe and then winds round the pole). An open path's ends count as
///     reaching the seam edge.
/// WrapMode::none reads every path as written. `closed`: the sequence is a ring whose last vertex
/// repeats the first; its winding is then counted.
UnwrappedPath unwrap_longitudes(const grid::LonLat* vertices, std::size_t count, bool closed, WrapMode mode);

}  // namespace qtmv::sites
