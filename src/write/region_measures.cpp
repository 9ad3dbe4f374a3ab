#include "write/region_measures.hpp"

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/PolygonArea.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "grid/qtm.hpp"
#include "common/first_exception.hpp"

namespace qtmv::write {

namespace {

/// Rings with more vertices than this are measured in chunks of kChunkVertices on all cores.
constexpr std::size_t kChunkVertices = 4096;
constexpr std::size_t kChunkFrom = 4 * kChunkVertices;

/// Longitudes (degrees) of the grid vertices strictly between lon_from and lon_to on the
/// parallel `lat` (a row line, or a pole line, where the octant corners are the vertices), in
/// the order met going from lon_from to lon_to. Computed as grid_vertex computes them, so that
/// they are the cells' own vertices to the bit.
void row_line_vertices(double lat, double lon_from, double lon_to, int level, std::vector<double>& out) {
  out.clear();
  const double lo = std::min(lon_from, lon_to), hi = std::max(lon_from, lon_to);
  if (std::fabs(lat) == 90.0) {
    for (double lon : {-90.0, 0.0, 90.0}) {
      if (lon > lo && lon < hi) out.push_back(lon);
    }
  } else {
    const double rows = static_cast<double>(grid::rows_per_octant(level));
    const double lat_local = std::fabs(lat);
    const auto r = static_cast<std::uint64_t>(std::llround((90.0 - lat_local) / 90.0 * rows));
    const bool north = lat >= 0;  // the equator's vertices are the same from either side
    const int first_octant = north ? 0 : 4;
    if (r == 0 || std::fabs(grid::grid_vertex(first_octant, r, 0, level).lat) != lat_local) return;  // not a row line
    for (int o = first_octant; o < first_octant + 4; ++o) {
      const double origin = grid::lon_from_local(o, 0.0);
      // The run's local longitudes (lon') in this octant.
      double local_lo = north ? lo - origin : origin - hi;
      double local_hi = north ? hi - origin : origin - lo;
      local_lo = std::max(local_lo, 0.0);
      local_hi = std::min(local_hi, 90.0);
      if (local_lo > local_hi) continue;
      const double per_degree = static_cast<double>(r) / 90.0;
      const auto k_first = static_cast<std::uint64_t>(std::max(0.0, std::floor(local_lo * per_degree) - 1));
      const auto k_last = std::min(r, static_cast<std::uint64_t>(std::ceil(local_hi * per_degree)) + 1);
      for (std::uint64_t k = k_first; k <= k_last; ++k) {
        const double lon = grid::grid_vertex(o, r, k, level).lon;
        if (lon > lo && lon < hi) out.push_back(lon);
      }
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  if (lon_to < lon_from) std::reverse(out.begin(), out.end());
}

/// Rough area (square metres) inside a ring in lon/lat, of either orientation: the sphere's
/// area between each edge and the equator by the trapezoid rule in sin(latitude), scaled to
/// the ellipsoid's area. Good to a few percent, enough to resolve a multiple of the whole.
double lonlat_ring_area(const std::vector<LonLat>& ring) {
  double sum = 0;  // steradians, signed
  const std::size_t n = ring.size();
  for (std::size_t k = 0; k < n; ++k) {
    const LonLat& p = ring[k];
    const LonLat& q = ring[(k + 1) % n];
    sum += (q.lon - p.lon) * grid::kDegree * 0.5 * (std::sin(p.lat * grid::kDegree) + std::sin(q.lat * grid::kDegree));
  }
  return std::fabs(sum) / (4 * grid::kPi) * GeographicLib::Geodesic::WGS84().EllipsoidArea();
}

/// Adds ring[from] and the row-line vertices up to ring[from + 1] (not included): the tracer drops
/// the vertices in the middle of runs along row lines; they are put back, so that every edge is
/// one cell edge and neighbouring regions share their geodesic edges exactly. Runs along the pole
/// lines get the octant corners back too, which keeps every edge there under 180 degrees of
/// longitude.
void add_edge_points(GeographicLib::PolygonArea& polygon, const std::vector<LonLat>& ring, std::size_t from, int level,
                     std::vector<double>& scratch) {
  const LonLat& a = ring[from];
  const LonLat& b = ring[(from + 1) % ring.size()];
  polygon.AddPoint(a.lat, a.lon);
  if (a.lat == b.lat) {
    row_line_vertices(a.lat, a.lon, b.lon, level, scratch);
    for (double lon : scratch) polygon.AddPoint(a.lat, lon);
  }
}

/// One piece of measuring work: edges [begin, end) of a ring (end - begin = its size: the whole
/// ring), or with `ends` the ring of its chunks' first vertices.
struct RingWork {
  const std::vector<LonLat>* ring;
  bool clockwise;
  std::size_t begin, end;
  bool ends = false;
};

/// The area on the left of a whole counter-clockwise ring (or the right of a clockwise one), in
/// [0, area of the ellipsoid); or, for a chunk, its signed area (its edges closed by a geodesic).
double measure(const RingWork& w, int level, std::vector<double>& scratch) {
  GeographicLib::PolygonArea polygon(GeographicLib::Geodesic::WGS84());
  const std::vector<LonLat>& ring = *w.ring;
  const bool whole = !w.ends && w.end - w.begin == ring.size();
  if (w.ends) {
    for (std::size_t k = 0; k < ring.size(); k += kChunkVertices) polygon.AddPoint(ring[k].lat, ring[k].lon);
  } else {
    for (std::size_t k = w.begin; k < w.end; ++k) add_edge_points(polygon, ring, k, level, scratch);
    if (!whole) polygon.AddPoint(ring[w.end % ring.size()].lat, ring[w.end % ring.size()].lon);
  }
  double perimeter = 0, area = 0;
  // Whole rings: sign = false, the area on the ring's inner side (left, or right when reversed),
  // never a negative remainder; so a ring around a pole gives the polar cap. Pieces: signed.
  polygon.Compute(w.clockwise, !whole, perimeter, area);
  return area;
}

/// A whole ring's area from its measure (or its pieces' sum), in [0, A): that area is known
/// modulo the ellipsoid's, A: a ring that holds both poles' lines from -180 to 180 (the whole
/// rectangle, less notches) encloses nearly A, which can come back as nearly 0. A rough area
/// from the lon/lat ring tells the two apart.
double settle(double area, const std::vector<LonLat>& ring) {
  const double ellipsoid = GeographicLib::Geodesic::WGS84().EllipsoidArea();
  area = std::fmod(area, ellipsoid);
  if (area < 0) area += ellipsoid;
  if (area < 0.5 * ellipsoid && lonlat_ring_area(ring) - area > 0.5 * ellipsoid) area += ellipsoid;
  return area;
}

}  // namespace

std::vector<double> region_areas(const std::vector<Region>& regions, std::size_t first, std::size_t last, int level) {
  // Every ring of the regions, as work: whole, or in chunks plus the ring of the chunks' ends.
  struct RingPlace {
    std::size_t region, work_begin, work_end;
    bool hole;
  };
  std::vector<RingWork> work;
  std::vector<RingPlace> rings;
  const auto add_ring = [&](std::size_t region, const std::vector<LonLat>& ring, bool hole) {
    const std::size_t begin = work.size();
    if (ring.size() < kChunkFrom) {
      work.push_back({&ring, hole, 0, ring.size()});
    } else {
      for (std::size_t k = 0; k < ring.size(); k += kChunkVertices) {
        work.push_back({&ring, hole, k, std::min(ring.size(), k + kChunkVertices)});
      }
      work.push_back({&ring, hole, 0, 0, true});
    }
    rings.push_back({region, begin, work.size(), hole});
  };
  for (std::size_t s = first; s < last; ++s) {
    for (const RegionPolygon& part : regions[s]) {
      add_ring(s, part.shell, false);
      for (const auto& hole : part.holes) add_ring(s, hole, true);
    }
  }
  std::vector<double> measured(work.size(), 0.0);
  FirstException failure;
#pragma omp parallel
  {
    std::vector<double> scratch;
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t k = 0; k < static_cast<std::int64_t>(work.size()); ++k) {
      failure.run([&] { measured[static_cast<std::size_t>(k)] = measure(work[static_cast<std::size_t>(k)], level, scratch); });
    }
  }
  failure.rethrow();
  std::vector<double> areas(last - first, 0.0);
  for (const RingPlace& r : rings) {
    double area = 0;
    for (std::size_t k = r.work_begin; k < r.work_end; ++k) area += measured[k];
    area = settle(area, *work[r.work_begin].ring);  // exact for a whole ring's [0, A) measure
    areas[r.region - first] += r.hole ? -area : area;
  }
  return areas;
}

double geodesic_length(const LonLat& a, const LonLat& b) {
  double s12 = 0;
  GeographicLib::Geodesic::WGS84().Inverse(a.lat, a.lon, b.lat, b.lon, s12);
  return s12;
}

}  // namespace qtmv::write
