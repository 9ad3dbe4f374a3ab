#include "write/region_tracer.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include "grid/qtm_checks.hpp"
#include "write/first_exception.hpp"

namespace qtmv::write {
namespace {

using grid::Cell;
using grid::Code;

/// One directed boundary edge of a region, with the region on its left.
struct Edge {
  LonLat from, to;
};

/// Angle (radians, in (0, 2 pi]) turned clockwise from direction d to direction t.
double clockwise_angle(double dx, double dy, double tx, double ty) {
  double a = std::atan2(dy, dx) - std::atan2(ty, tx);
  while (a <= 0) a += 2 * grid::kPi;
  while (a > 2 * grid::kPi) a -= 2 * grid::kPi;
  return a;
}

/// Drops vertices in the middle of straight runs along a parallel or a meridian (exactly
/// equal latitudes or longitudes): rows of cells make long runs of them.
std::vector<LonLat> drop_straight_runs(const std::vector<LonLat>& ring) {
  const std::size_t n = ring.size();
  std::vector<LonLat> out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const LonLat& prev = ring[(k + n - 1) % n];
    const LonLat& here = ring[k];
    const LonLat& next = ring[(k + 1) % n];
    const bool along_parallel = prev.lat == here.lat && here.lat == next.lat;
    const bool along_meridian = prev.lon == here.lon && here.lon == next.lon;
    if (!along_parallel && !along_meridian) out.push_back(here);
  }
  return out;
}

/// Cuts a closed walk that passes a vertex more than once into simple rings. Where a region
/// meets itself at a vertex, no pairing of the edges there suits every case: lobes that touch
/// at a point, a hole that touches its shell, holes that touch each other. Each loop cut off
/// here is a shell (counter-clockwise) or a hole (clockwise) of its own.
std::vector<std::vector<LonLat>> split_at_repeated_vertices(const std::vector<LonLat>& walk) {
  std::vector<std::vector<LonLat>> rings;
  std::vector<LonLat> stack;
  std::map<std::pair<double, double>, std::size_t> position;  // vertex -> its index in stack
  for (const LonLat& p : walk) {
    const auto found = position.find({p.lon, p.lat});
    if (found == position.end()) {
      position.emplace(std::make_pair(p.lon, p.lat), stack.size());
      stack.push_back(p);
      continue;
    }
    // The walk came back to p: the stretch since p's first visit is a closed loop.
    const std::size_t first = found->second;
    rings.emplace_back(stack.begin() + static_cast<std::ptrdiff_t>(first), stack.end());
    for (std::size_t k = first + 1; k < stack.size(); ++k) position.erase({stack[k].lon, stack[k].lat});
    stack.resize(first + 1);
  }
  rings.push_back(std::move(stack));
  return rings;
}

/// Even-odd test of a point against a ring that does not pass through it.
bool ring_contains(const std::vector<LonLat>& ring, const LonLat& p) {
  bool inside = false;
  const std::size_t n = ring.size();
  for (std::size_t k = 0, m = n - 1; k < n; m = k++) {
    const LonLat& a = ring[k];
    const LonLat& b = ring[m];
    if ((a.lat > p.lat) != (b.lat > p.lat)) {
      const double lon_at = a.lon + (p.lat - a.lat) / (b.lat - a.lat) * (b.lon - a.lon);
      if (p.lon < lon_at) inside = !inside;
    }
  }
  return inside;
}

struct Box {
  double lon_min = 1e9, lon_max = -1e9, lat_min = 1e9, lat_max = -1e9;
  void add(const LonLat& p) {
    lon_min = std::min(lon_min, p.lon);
    lon_max = std::max(lon_max, p.lon);
    lat_min = std::min(lat_min, p.lat);
    lat_max = std::max(lat_max, p.lat);
  }
  bool contains(const LonLat& p) const {
    return p.lon >= lon_min && p.lon <= lon_max && p.lat >= lat_min && p.lat <= lat_max;
  }
};

/// Links one site's boundary edges into rings and groups them into polygons.
Region link_rings(std::vector<Edge>& edges) {
  // Sorted by both ends, so that the rings come out the same whatever order the edges came in.
  std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) {
    return point_less(a.from, b.from) || (same_point(a.from, b.from) && point_less(a.to, b.to));
  });
  std::vector<char> used(edges.size(), 0);
  auto next_edge = [&](std::size_t e) {
    const LonLat at = edges[e].to;
    auto first = std::lower_bound(edges.begin(), edges.end(), at,
                                  [](const Edge& x, const LonLat& p) { return point_less(x.from, p); });
    std::size_t best = edges.size();
    double best_angle = 1e300;
    // Reverse of the incoming edge; the region lies clockwise from it, so the outgoing edge of
    // the same wedge is the first one met turning clockwise.
    const double dx = edges[e].from.lon - at.lon, dy = edges[e].from.lat - at.lat;
    for (auto it = first; it != edges.end() && same_point(it->from, at); ++it) {
      const std::size_t k = static_cast<std::size_t>(it - edges.begin());
      if (used[k]) continue;
      const double angle = clockwise_angle(dx, dy, it->to.lon - at.lon, it->to.lat - at.lat);
      if (angle < best_angle) {
        best_angle = angle;
        best = k;
      }
    }
    return best;
  };

  std::vector<std::vector<LonLat>> shells, holes;
  for (std::size_t start = 0; start < edges.size(); ++start) {
    if (used[start]) continue;
    std::vector<LonLat> ring;
    std::size_t e = start;
    while (e < edges.size() && !used[e]) {
      used[e] = 1;
      ring.push_back(edges[e].from);
      e = next_edge(e);
    }
    for (std::vector<LonLat>& simple : split_at_repeated_vertices(ring)) {
      simple = drop_straight_runs(simple);
      if (simple.size() < 3) continue;
      (planar_ring_area(simple) > 0 ? shells : holes).push_back(std::move(simple));
    }
  }

  Region region(shells.size());
  std::vector<Box> boxes(shells.size());
  std::vector<double> areas(shells.size());
  for (std::size_t s = 0; s < shells.size(); ++s) {
    for (const LonLat& p : shells[s]) boxes[s].add(p);
    areas[s] = planar_ring_area(shells[s]);
    region[s].shell = std::move(shells[s]);
  }
  for (auto& hole : holes) {
    // The middle of an edge of the hole is on no other ring, so it is strictly inside or
    // outside each shell; the smallest shell around it owns the hole.
    const LonLat probe{0.5 * (hole[0].lon + hole[1].lon), 0.5 * (hole[0].lat + hole[1].lat)};
    std::size_t owner = region.size();
    for (std::size_t s = 0; s < region.size(); ++s) {
      if (boxes[s].contains(probe) && ring_contains(region[s].shell, probe) &&
          (owner == region.size() || areas[s] < areas[owner])) {
        owner = s;
      }
    }
    if (owner == region.size()) throw std::logic_error("region tracer: a hole lies in no shell of its region");
    region[owner].holes.push_back(std::move(hole));
  }
  return region;
}

}  // namespace

int drawn_ring(const Cell& c, int level, LonLat ring[grid::kMaxPolygonCorners], int across[grid::kMaxPolygonCorners]) {
  const int n = grid::cell_polygon(c, level, ring);
  if (n == 4) {  // the pole quadrilateral: left side, bottom, right side, the pole line
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourVertical;
    across[2] = grid::kNeighbourRight;
    across[3] = kAcrossPoleLine;
  } else if (grid::is_up(c)) {  // apex, lower left, lower right
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourVertical;
    across[2] = grid::kNeighbourRight;
  } else {  // upper left, bottom, upper right
    across[0] = grid::kNeighbourLeft;
    across[1] = grid::kNeighbourRight;
    across[2] = grid::kNeighbourVertical;
  }
  return n;
}

double planar_ring_area(const std::vector<LonLat>& ring) {
  double twice = 0;
  const std::size_t n = ring.size();
  for (std::size_t k = 0; k < n; ++k) {
    const LonLat& p = ring[k];
    const LonLat& q = ring[(k + 1) % n];
    twice += (p.lon - q.lon) * (p.lat + q.lat);
  }
  return 0.5 * twice;
}

std::vector<Region> trace_regions(const label::Outlines& outlines) {
  const int level = outlines.level;
  grid::require_level(level);
  const std::vector<label::OutlineCell>& cells = outlines.cells;
  const auto n = static_cast<std::int64_t>(cells.size());

  // Boundary edges of every region, gathered per site.
  std::vector<std::vector<Edge>> edges_of(static_cast<std::size_t>(outlines.site_count));
  FirstException failure;
#pragma omp parallel
  {
    std::vector<std::pair<std::int32_t, Edge>> local;
#pragma omp for schedule(static)
    for (std::int64_t k = 0; k < n; ++k) {
      failure.run([&] {
        const label::OutlineCell& outline = cells[static_cast<std::size_t>(k)];
        const Cell cell = grid::cell_of(outline.code, level);
        LonLat ring[grid::kMaxPolygonCorners];
        int across[grid::kMaxPolygonCorners];
        const int corners = drawn_ring(cell, level, ring, across);
        Code nb[3];
        grid::neighbours(outline.code, level, nb);
        for (int e = 0; e < corners; ++e) {
          const LonLat& from = ring[e];
          const LonLat& to = ring[(e + 1) % corners];
          const bool on_border = across[e] == kAcrossPoleLine ||
                                 (std::fabs(from.lon) == 180.0 && std::fabs(to.lon) == 180.0);  // cut at +-180
          // Only a boundary cell has a neighbour of another site.
          if (on_border || (outline.boundary &&
                              label::site_of_near(cells, static_cast<std::size_t>(k), nb[across[e]]) != outline.site)) {
            local.push_back({outline.site, {from, to}});
          }
        }
      });
    }
#pragma omp critical
    failure.run([&] {
      for (const auto& [site, edge] : local) edges_of[static_cast<std::size_t>(site)].push_back(edge);
    });
  }
  failure.rethrow();

  std::vector<Region> regions(static_cast<std::size_t>(outlines.site_count));
#pragma omp parallel for schedule(dynamic, 1)
  for (std::int32_t site = 0; site < outlines.site_count; ++site) {
    failure.run([&] { regions[static_cast<std::size_t>(site)] = link_rings(edges_of[static_cast<std::size_t>(site)]); });
  }
  failure.rethrow();
  return regions;
}

std::vector<Region> trace_regions(int level, const std::int32_t* labels, std::int32_t site_count) {
  grid::require_level(level);
  return trace_regions(label::outlines_of_dense(level, labels, nullptr, site_count));
}

}  // namespace qtmv::write
