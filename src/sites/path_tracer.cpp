#include "sites/path_tracer.hpp"

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/GeodesicLine.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "grid/qtm_checks.hpp"

namespace qtmv::sites {

namespace {

grid::Code code_at(const grid::LonLat& p, int level) {
  return grid::lonlat_to_code(p.lon, std::max(-90.0, std::min(90.0, p.lat)), level);
}

Vec3 vector_at(const grid::LonLat& p) {
  return grid::unit_vector(grid::normalise_lon(p.lon), std::max(-90.0, std::min(90.0, p.lat)));
}

bool same(const Vec3& a, const Vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

/// Index the next piece will get: site cells hold 32-bit piece indices.
std::uint32_t next_piece_index(const label::SiteArray<SitePiece>& pieces) {
  if (pieces.size() >= UINT32_MAX) {
    throw ReadError("more than " + std::to_string(UINT32_MAX) + " pieces of lines and rings: use a lower level");
  }
  return static_cast<std::uint32_t>(pieces.size());
}

// Steps below this (degrees along the edge) are not bisected further.
constexpr double kFinestStepDegrees = 1e-9;

}  // namespace

bool share_edge(grid::Code a, grid::Code b, int level) {
  grid::Code n[3];
  grid::neighbours(a, level, n);
  return n[0] == b || n[1] == b || n[2] == b;
}

bool share_vertex(grid::Code a, grid::Code b, int level, grid::LonLat* vertex) {
  if (a == b) return true;
  grid::LonLat va[3], vb[3];
  grid::cell_vertices(grid::cell_of(a, level), level, va);
  grid::cell_vertices(grid::cell_of(b, level), level, vb);
  for (const auto& p : va) {
    for (const auto& q : vb) {
      if (grid::chord2(grid::unit_vector(p.lon, p.lat), grid::unit_vector(q.lon, q.lat)) < 1e-24) {
        if (vertex) *vertex = p;
        return true;
      }
    }
  }
  return false;
}

/// One edge of the path: its shape, parametrised by t in [0, 1].
struct PathTracer::Edge {
  grid::LonLat from, to;
  bool geodesic = false;
  GeographicLib::GeodesicLine line;
  double arc = 0;           // geodesic: arc length on the auxiliary sphere (degrees)
  double length_bound = 0;  // upper bound of the edge's length (degrees of great-circle arc)

  grid::LonLat at(double t) const {
    if (t <= 0.0) return from;
    if (t >= 1.0) return to;
    if (!geodesic) return {from.lon + t * (to.lon - from.lon), from.lat + t * (to.lat - from.lat)};
    double lat, lon, unused;
    line.GenPosition(true, t * arc, GeographicLib::GeodesicLine::LATITUDE | GeographicLib::GeodesicLine::LONGITUDE |
                                        GeographicLib::GeodesicLine::LONG_UNROLL,
                     lat, lon, unused, unused, unused, unused, unused, unused);
    return {lon, lat};
  }
};

PathTracer::PathTracer(int level, EdgeShape shape)
    : level_(level), shape_(shape), max_piece_(max_piece_degrees(level)) {
  grid::require_level(level);
}

void PathTracer::refine(const Edge& edge, double t0, grid::Code c0, double t1, grid::Code c1, std::uint32_t piece,
                        std::vector<CellHit>& hits, int depth) {
  if (c0 == c1) return;
  if (share_edge(c0, c1, level_)) {
    hits.push_back({c1, piece});
    return;
  }
  if (depth > 60 || (t1 - t0) * edge.length_bound < kFinestStepDegrees) {
    // The edge passes through a grid vertex: the cell that owns the vertex point is passed too.
    ++vertex_steps_;
    grid::LonLat vertex;
    if (share_vertex(c0, c1, level_, &vertex)) {
      const grid::Code owner = grid::lonlat_to_code(vertex.lon, vertex.lat, level_);
      if (owner != c0 && owner != c1) hits.push_back({owner, piece});
    }
    hits.push_back({c1, piece});
    return;
  }
  const double tm = 0.5 * (t0 + t1);
  const grid::Code cm = code_at(edge.at(tm), level_);
  refine(edge, t0, c0, tm, cm, piece, hits, depth + 1);
  if (cm != c0 && (hits.empty() || hits.back().code != cm || hits.back().piece != piece)) hits.push_back({cm, piece});
  refine(edge, tm, cm, t1, c1, piece, hits, depth + 1);
}

void PathTracer::trace(const grid::LonLat* vertices, std::size_t count, std::int32_t site,
                       label::SiteArray<SitePiece>& pieces, std::vector<CellHit>& hits,
                       std::vector<grid::LonLat>* samples, const std::uint8_t* straight) {
  if (count == 0) return;
  const std::size_t first_piece = pieces.size();
  const auto& wgs84 = GeographicLib::Geodesic::WGS84();
  auto add_hit = [&](grid::Code code, std::uint32_t piece) {
    if (hits.empty() || hits.back().code != code || hits.back().piece != piece) hits.push_back({code, piece});
  };
  if (samples) samples->push_back(vertices[0]);
  grid::LonLat prev = vertices[0];
  Vec3 prev_vector = vector_at(prev);
  grid::Code prev_code = code_at(prev, level_);
  double lon_shift = 0.0;  // geodesic: multiple of 360 that keeps the samples' longitudes continuous
  for (std::size_t k = 1; k < count; ++k) {
    Edge edge;
    edge.from = prev;
    edge.to = {vertices[k].lon + lon_shift, vertices[k].lat};
    if (shape_ == EdgeShape::geodesic && !(straight && straight[k - 1])) {
      edge.geodesic = true;
      edge.line = wgs84.InverseLine(edge.from.lat, edge.from.lon, edge.to.lat, edge.to.lon);
      edge.arc = edge.line.Arc();
      // The geodesic takes the short way: unroll the end's longitude to where it arrives.
      double end_lat, end_lon, unused;
      edge.line.GenPosition(true, edge.arc,
                            GeographicLib::GeodesicLine::LATITUDE | GeographicLib::GeodesicLine::LONGITUDE |
                                GeographicLib::GeodesicLine::LONG_UNROLL,
                            end_lat, end_lon, unused, unused, unused, unused, unused, unused);
      const double turns = std::round((end_lon - edge.to.lon) / 360.0);
      lon_shift += 360.0 * turns;
      edge.to.lon += 360.0 * turns;
      // The auxiliary sphere's arc differs from the geocentric angle by well under 1%.
      edge.length_bound = 1.01 * edge.arc;
    } else {
      // |d(path)/dt| <= sqrt(dlat^2 + (cos(lat)_max dlon)^2) along the straight lon/lat segment.
      const double dlat = edge.to.lat - edge.from.lat, dlon = edge.to.lon - edge.from.lon;
      const bool crosses_equator = (edge.from.lat <= 0) != (edge.to.lat <= 0);
      const double min_abs_lat = crosses_equator ? 0.0 : std::min(std::fabs(edge.from.lat), std::fabs(edge.to.lat));
      const double cos_max = std::cos(min_abs_lat * grid::kDegree);
      edge.length_bound = std::sqrt(dlat * dlat + cos_max * dlon * cos_max * dlon);
    }
    const double steps_needed = std::ceil(edge.length_bound / max_piece_);
    const std::uint64_t steps = steps_needed < 1.0 ? 1 : static_cast<std::uint64_t>(steps_needed);
    double prev_t = 0.0;
    for (std::uint64_t s = 1; s <= steps; ++s) {
      const double t = s == steps ? 1.0 : static_cast<double>(s) / static_cast<double>(steps);
      const grid::LonLat p = edge.at(t);
      const grid::Code code = code_at(p, level_);
      const Vec3 v = vector_at(p);
      if (samples) samples->push_back(p);
      if (!same(v, prev_vector)) {
        const std::uint32_t piece = next_piece_index(pieces);
        pieces.push_back({prev_vector, v, site});
        add_hit(prev_code, piece);
        refine(edge, prev_t, prev_code, t, code, piece, hits, 0);
      }
      prev_t = t;
      prev = p;
      prev_vector = v;
      prev_code = code;
    }
  }
  if (pieces.size() == first_piece) {  // a single point
    const std::uint32_t piece = next_piece_index(pieces);
    pieces.push_back({prev_vector, prev_vector, site});
    add_hit(prev_code, piece);
  }
}

}  // namespace qtmv::sites
