#include "sites/lon_unwrap.hpp"

#include <cmath>

namespace qtmv::sites {
namespace {

enum class EdgeKind { ordinary, jump, seam, polar };

bool at_pole(const grid::LonLat& p) { return std::fabs(p.lat) == 90.0; }

EdgeKind classify(const grid::LonLat& a, const grid::LonLat& b) {
  if (at_pole(a) || at_pole(b)) return EdgeKind::polar;
  if (std::fabs(a.lon) == 180.0 && std::fabs(b.lon) == 180.0 && a.lon != b.lon) return EdgeKind::seam;
  if (std::fabs(b.lon - a.lon) > 180.0) return EdgeKind::jump;
  return EdgeKind::ordinary;
}

/// Edges drawn as their coordinates say whatever the edge shape: pole lines, and seam edges when
/// the path is read as written.
bool straight_edge(EdgeKind kind, const grid::LonLat& a, const grid::LonLat& b, bool as_written) {
  if (kind == EdgeKind::polar) return at_pole(a) && at_pole(b) && a.lat == b.lat && a.lon != b.lon;
  return kind == EdgeKind::seam && as_written;
}

}  // namespace

UnwrappedPath unwrap_longitudes(const grid::LonLat* vertices, std::size_t count, bool closed, WrapMode mode) {
  UnwrappedPath out;
  out.vertices.assign(vertices, vertices + count);
  if (count < 2) return out;
  const std::size_t edges = count - 1;
  std::vector<EdgeKind> kinds(edges);
  bool has_jump = false;
  for (std::size_t k = 0; k < edges; ++k) {
    kinds[k] = classify(vertices[k], vertices[k + 1]);
    has_jump = has_jump || kinds[k] == EdgeKind::jump;
  }
  // Cut data reaches a seam edge along the meridian +-180 or from a pole (caps, bands, Natural
  // Earth's Antarctica). A seam edge between two edges that do neither steps across +-180 with a
  // vertex on each side (world-atlas's Antarctica, whose coast goes round the globe; a line
  // written through (180, y) and (-180, y)). An open path's end counts as reaching it.
  auto reaches_seam = [&](std::size_t k) {  // edge k runs along +-180 or to a pole
    return kinds[k] == EdgeKind::polar ||
           (vertices[k].lon == vertices[k + 1].lon && std::fabs(vertices[k].lon) == 180.0);
  };
  bool steps_across = false;
  for (std::size_t k = 0; k < edges && !steps_across; ++k) {
    if (kinds[k] != EdgeKind::seam) continue;
    const bool first = k == 0, last = k + 1 == edges;
    if (!closed && (first || last)) continue;
    steps_across = !reaches_seam(first ? edges - 1 : k - 1) && !reaches_seam(last ? 0 : k + 1);
  }
  const bool as_written = mode == WrapMode::none || (!has_jump && !steps_across);
  out.straight.resize(edges);
  for (std::size_t k = 1; k < count; ++k) {
    out.straight[k - 1] = straight_edge(kinds[k - 1], vertices[k - 1], vertices[k], as_written) ? 1 : 0;
  }
  if (!as_written) {
    double shift = 0.0;  // multiple of 360 added to the input longitude of the current vertex
    for (std::size_t k = 1; k < count; ++k) {
      const grid::LonLat& a = vertices[k - 1];
      const grid::LonLat& b = vertices[k];
      const double step = b.lon - a.lon;
      if (kinds[k - 1] == EdgeKind::seam) {
        shift += a.lon - b.lon;  // along the meridian: same unwrapped longitude
        ++out.short_way_edges;
      } else if (kinds[k - 1] == EdgeKind::jump) {
        shift += step > 0 ? -360.0 * std::ceil((step - 180.0) / 360.0) : 360.0 * std::ceil((-step - 180.0) / 360.0);
        ++out.short_way_edges;
      }
      out.vertices[k].lon = b.lon + shift;
    }
  }
  if (closed) out.winding = static_cast<int>(std::lround((out.vertices.back().lon - out.vertices.front().lon) / 360.0));
  return out;
}

}  // namespace qtmv::sites
