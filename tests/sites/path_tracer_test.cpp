// Line tracing: the cells of a traced line form a chain without gaps, points sampled densely along
// each segment (in the -edges sense, computed here independently) fall in the listed cells, and
// the pieces are short arcs that start and end on the line.
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/GeodesicLine.hpp>

#include <cmath>
#include <set>
#include <vector>

#include "grid/qtm.hpp"
#include "sites/lon_unwrap.hpp"
#include "sites/path_tracer.hpp"

namespace qtmv::sites {
namespace {

using grid::LonLat;

struct TracedLine {
  label::SiteArray<SitePiece> pieces;
  std::vector<CellHit> hits;
};

TracedLine trace(const std::vector<LonLat>& vertices, int level, EdgeShape shape, WrapMode wrap = WrapMode::automatic) {
  const UnwrappedPath path = unwrap_longitudes(vertices.data(), vertices.size(), false, wrap);
  PathTracer tracer(level, shape);
  TracedLine out;
  tracer.trace(path.vertices.data(), path.vertices.size(), 7, out.pieces, out.hits);
  return out;
}

// Dense samples of each segment: straight in lon/lat between the given (already unwrapped)
// vertices, or the WGS84 geodesic.
std::vector<LonLat> dense_samples(const std::vector<LonLat>& v, EdgeShape shape, int per_segment) {
  std::vector<LonLat> out;
  const auto& wgs84 = GeographicLib::Geodesic::WGS84();
  for (std::size_t k = 1; k < v.size(); ++k) {
    if (shape == EdgeShape::lonlat) {
      for (int s = 0; s <= per_segment; ++s) {
        const double t = static_cast<double>(s) / per_segment;
        out.push_back({v[k - 1].lon + t * (v[k].lon - v[k - 1].lon), v[k - 1].lat + t * (v[k].lat - v[k - 1].lat)});
      }
    } else {
      const GeographicLib::GeodesicLine line = wgs84.InverseLine(v[k - 1].lat, v[k - 1].lon, v[k].lat, v[k].lon);
      for (int s = 0; s <= per_segment; ++s) {
        double lat, lon;
        line.Position(line.Distance() * s / per_segment, lat, lon);
        out.push_back({lon, lat});
      }
    }
  }
  return out;
}

void expect_chain_and_cover(const std::vector<LonLat>& vertices, const std::vector<LonLat>& unwrapped, int level,
                            EdgeShape shape) {
  SCOPED_TRACE("level " + std::to_string(level) + (shape == EdgeShape::geodesic ? " geodesic" : " lonlat"));
  const TracedLine t = trace(vertices, level, shape);
  ASSERT_FALSE(t.hits.empty());
  // A chain: consecutive cells are the same cell or neighbours (edge or vertex).
  for (std::size_t k = 1; k < t.hits.size(); ++k) {
    const grid::Code a = t.hits[k - 1].code, b = t.hits[k].code;
    EXPECT_TRUE(a == b || share_edge(a, b, level) || share_vertex(a, b, level)) << "hit " << k << ": " << a << " " << b;
  }
  // Dense samples fall in listed cells.
  std::set<grid::Code> listed;
  for (const auto& h : t.hits) listed.insert(h.code);
  int missing = 0;
  for (const LonLat& p : dense_samples(unwrapped, shape, 4000)) {
    const grid::Code c = grid::lonlat_to_code(p.lon, p.lat, level);
    if (!listed.count(c)) {
      ++missing;
      ADD_FAILURE() << "sample " << p.lon << " " << p.lat << " in cell " << c;
    }
  }
  EXPECT_EQ(missing, 0);
  // Pieces: short arcs; each piece's ends fall in cells listed for it.
  const double max_chord = 2.0 * std::sin(0.5 * max_piece_degrees(level) * grid::kDegree) * 1.02;
  for (std::size_t p = 0; p < t.pieces.size(); ++p) {
    EXPECT_LE(std::sqrt(grid::chord2(t.pieces[p].a, t.pieces[p].b)), max_chord) << "piece " << p;
    EXPECT_EQ(t.pieces[p].site, 7);
  }
  std::vector<std::set<grid::Code>> cells_of_piece(t.pieces.size());
  for (const auto& h : t.hits) cells_of_piece.at(h.piece).insert(h.code);
  for (std::size_t p = 0; p < t.pieces.size(); ++p) {
    for (const grid::Vec3& v : {t.pieces[p].a, t.pieces[p].b}) {
      const double lon = std::atan2(v.y, v.x) / grid::kDegree, lat = std::asin(std::max(-1.0, std::min(1.0, v.z))) / grid::kDegree;
      const grid::Code c = grid::lonlat_to_code(lon, lat, level);
      // A piece end exactly on a cell boundary or vertex may round to the other side: accept a neighbour.
      bool ok = cells_of_piece[p].count(c) > 0;
      for (grid::Code listed_cell : cells_of_piece[p]) ok = ok || share_vertex(c, listed_cell, level);
      EXPECT_TRUE(ok) << "piece " << p << " end " << lon << " " << lat << " cell " << c << " first listed " << *cells_of_piece[p].begin();
    }
  }
}

TEST(PathTracer, LinesAtSeveralLevelsCoverDenseSamplesWithoutGaps) {
  struct Case {
    std::vector<LonLat> vertices, unwrapped;
  };
  const std::vector<Case> cases = {
      {{{2, 3}, {47.5, 41.2}, {95, 60}, {100, -30}}, {{2, 3}, {47.5, 41.2}, {95, 60}, {100, -30}}},
      // Along the equator and along the octant edge lon 90, through grid vertices.
      {{{-10, 0}, {100, 0}}, {{-10, 0}, {100, 0}}},
      {{{90, -60}, {90, 60}}, {{90, -60}, {90, 60}}},
      {{{0, 0}, {45, 45}, {90, 0}}, {{0, 0}, {45, 45}, {90, 0}}},
      // Crossing +-180, and touching a pole.
      {{{170, 10}, {-170, 20}, {-175, -5}}, {{170, 10}, {190, 20}, {185, -5}}},
      {{{-30, 70}, {-30, 90}, {150, 80}}, {{-30, 70}, {-30, 90}, {150, 80}}},
      {{{-120, -89.99}, {60, -89.99}}, {{-120, -89.99}, {60, -89.99}}},
  };
  for (const Case& c : cases) {
    for (int level : {2, 5, 9}) {
      expect_chain_and_cover(c.vertices, c.unwrapped, level, EdgeShape::lonlat);
    }
  }
}

TEST(PathTracer, GeodesicsCrossingTheAntimeridianAndPassingAPole) {
  // (0, 80) to (180, 80): the geodesic runs over the north pole; (170, -20) to (-170, -25) the
  // short way across +-180.
  const std::vector<std::vector<LonLat>> lines = {
      {{0, 80}, {180, 80}}, {{170, -20}, {-170, -25}, {-160, 10}}, {{-45, -70}, {135, -70}}, {{10, 0}, {80, 1}}};
  for (const auto& line : lines) {
    for (int level : {3, 7, 11}) expect_chain_and_cover(line, line, level, EdgeShape::geodesic);
  }
  // Over the pole: the pole cells are reached.
  const TracedLine t = trace({{0, 80}, {180, 80}}, 6, EdgeShape::geodesic);
  std::set<grid::Code> cells;
  for (const auto& h : t.hits) cells.insert(h.code);
  EXPECT_TRUE(cells.count(grid::lonlat_to_code(0, 90, 6)) || cells.count(grid::lonlat_to_code(90, 90, 6)));
}

TEST(PathTracer, PointsAndDegenerateLines) {
  PathTracer tracer(10, EdgeShape::lonlat);
  label::SiteArray<SitePiece> pieces;
  std::vector<CellHit> hits;
  const LonLat p{12.5, -33.25};
  tracer.trace(&p, 1, 3, pieces, hits);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_EQ(pieces[0].a.x, pieces[0].b.x);
  EXPECT_EQ(pieces[0].site, 3);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].code, grid::lonlat_to_code(12.5, -33.25, 10));
  const LonLat same[3] = {p, p, p};
  pieces.clear();
  hits.clear();
  tracer.trace(same, 3, 3, pieces, hits);
  EXPECT_EQ(pieces.size(), 1u);
  EXPECT_EQ(hits.size(), 1u);
}

TEST(LonUnwrap, ShortWayAcrossTheAntimeridianSeamEdgesAndPoles) {
  // world-atlas's Fiji steps from -180 to +179.4: joined the short way.
  const LonLat fiji[] = {{-180, -16.07}, {-179.8, -16.0}, {-180, -16.56}, {179.36, -16.8}, {179.41, -16.38},
                         {180, -16.07}, {-180, -16.07}};
  const UnwrappedPath f = unwrap_longitudes(fiji, 7, true, WrapMode::automatic);
  EXPECT_DOUBLE_EQ(f.vertices[3].lon, 179.36 - 360);
  EXPECT_DOUBLE_EQ(f.vertices[5].lon, -180);
  EXPECT_DOUBLE_EQ(f.vertices[6].lon, -180);  // a seam edge: along the meridian
  EXPECT_EQ(f.winding, 0);
  // A ring round the north pole winds once.
  std::vector<LonLat> cap;
  for (int lon = -180; lon < 180; lon += 30) cap.push_back({double(lon), 75});
  cap.push_back(cap.front());
  EXPECT_EQ(unwrap_longitudes(cap.data(), cap.size(), true, WrapMode::automatic).winding, 1);
  EXPECT_EQ(unwrap_longitudes(cap.data(), cap.size(), true, WrapMode::none).winding, 0);
  // Natural Earth's Antarctica detours through the pole: kept flat, no winding.
  const LonLat ne[] = {{-180, -84}, {0, -70}, {180, -84}, {180, -90}, {-180, -90}, {-180, -84}};
  EXPECT_EQ(unwrap_longitudes(ne, 6, true, WrapMode::automatic).winding, 0);
  // A line from -180 to +180 along the equator with no crossing edge: read flat, all round.
  const LonLat equator[] = {{-180, 0}, {180, 0}};
  EXPECT_DOUBLE_EQ(unwrap_longitudes(equator, 2, false, WrapMode::automatic).vertices[1].lon, 180);
  // world-atlas's Antarctica closes with a seam edge: winds once.
  const LonLat wa[] = {{-180, -84}, {0, -70}, {180, -84}, {-180, -84}};
  EXPECT_EQ(std::abs(unwrap_longitudes(wa, 4, true, WrapMode::automatic).winding), 1);
}

/// The longitudes of a ring read with -wrap auto, and what the reading changed.
UnwrappedPath read_ring(std::vector<LonLat> ring) {
  ring.push_back(ring.front());
  return unwrap_longitudes(ring.data(), ring.size(), true, WrapMode::automatic);
}

bool as_written(const UnwrappedPath& path, std::vector<LonLat> ring) {
  ring.push_back(ring.front());
  if (path.vertices.size() != ring.size() || path.short_way_edges != 0) return false;
  for (std::size_t k = 0; k < ring.size(); ++k) {
    if (path.vertices[k].lon != ring[k].lon) return false;
  }
  return true;
}

TEST(LonUnwrap, CutRingsAreReadAsWritten) {
  // Caps, both ways round, at the pole or at 89.999 (Natural Earth), and bands round the globe:
  // their seam edges are whole parallels and their pole lines run along the pole.
  const std::vector<std::vector<LonLat>> cut = {
      {{-180, 86}, {180, 86}, {180, 90}, {-180, 90}},
      {{-180, 84}, {-180, 90}, {180, 90}, {180, 84}},
      {{-180, -80}, {180, -80}, {180, -90}, {-180, -90}},
      {{-180, 86}, {180, 86}, {180, 89.999}, {-180, 89.999}},
      {{-180, -60}, {180, -60}, {180, 60}, {-180, 60}},
      // Natural Earth's Antarctica, down the meridian to -90 or to -89.999.
      {{-180, -84}, {0, -70}, {180, -84}, {180, -90}, {-180, -90}},
      {{-180, -84}, {0, -70}, {180, -84}, {180, -89.999}, {-180, -89.999}},
      // ogr2ogr -wrapdateline: a polygon's half on each side, along +-180.
      {{170, -20}, {180, -20}, {180, -10}, {170, -10}},
  };
  for (const auto& ring : cut) {
    const UnwrappedPath path = read_ring(ring);
    EXPECT_TRUE(as_written(path, ring)) << ring[0].lon << " " << ring[0].lat << " " << ring[1].lon << " " << ring[1].lat;
    EXPECT_EQ(path.winding, 0);
  }
  // The cap's seam edge and pole line are traced straight even with geodesic edges.
  const UnwrappedPath cap = read_ring(cut[0]);
  EXPECT_EQ(cap.straight, (std::vector<std::uint8_t>{1, 0, 1, 0}));
}

TEST(LonUnwrap, TheBoundaryBetweenCutAndUncutRings) {
  // A seam edge that joins a coast going round the globe directly closes it round the pole
  // (world-atlas); the same ring reaching the seam along +-180 is cut data, read as written.
  const UnwrappedPath joined = read_ring({{-180, -84}, {0, -70}, {180, -84}});
  EXPECT_EQ(joined.winding, 1);
  EXPECT_EQ(joined.short_way_edges, 1u);
  const std::vector<LonLat> reached = {{-180, -84}, {0, -70}, {180, -84}, {180, -85}, {-180, -85}};
  EXPECT_TRUE(as_written(read_ring(reached), reached));
  // The parallel written as two edges through 0 is no seam edge: the ring is read as written, a
  // band between the coast and the parallel.
  const std::vector<LonLat> band = {{-180, -84}, {0, -70}, {180, -84}, {0, -84}};
  EXPECT_TRUE(as_written(read_ring(band), band));
  // A seam edge needs both ends exactly on +-180: at 179.9999 the cap's long edges are jumps,
  // joined the short way (and the reader warns).
  const UnwrappedPath near = read_ring({{-180, 86}, {179.9999, 86}, {179.9999, 90}, {-180, 90}});
  EXPECT_EQ(near.short_way_edges, 1u);
  EXPECT_NEAR(near.vertices[1].lon, -180.0001, 1e-9);
  // An edge of exactly 180 degrees is not a jump; one a little longer is.
  EXPECT_TRUE(as_written(read_ring({{-90, 0}, {90, 0}, {90, 10}}), {{-90, 0}, {90, 0}, {90, 10}}));
  EXPECT_EQ(read_ring({{-90, 0}, {90.5, 0}, {90.5, 10}}).short_way_edges, 2u);  // out and back
  // A jump makes every seam edge of the ring zero length (world-atlas's Fiji).
  const UnwrappedPath fiji = read_ring({{-180, -16}, {-175, -15}, {-180, -18}, {175, -19}, {176, -16}, {180, -16}});
  EXPECT_EQ(fiji.short_way_edges, 2u);
  EXPECT_EQ(fiji.winding, 0);
  EXPECT_DOUBLE_EQ(fiji.vertices.back().lon, -180);
  // A square written across +-180 with a vertex on each side: its seam edges step across.
  const UnwrappedPath square =
      read_ring({{170, 10}, {180, 10}, {-180, 10}, {-170, 10}, {-170, 20}, {-180, 20}, {180, 20}, {170, 20}});
  EXPECT_EQ(square.short_way_edges, 2u);
  EXPECT_EQ(square.winding, 0);
  EXPECT_DOUBLE_EQ(square.vertices[3].lon, 190);
  // So does a line; one that only ends on +-180 is read as written (the whole parallel).
  const LonLat line[] = {{170, 10}, {180, 10}, {-180, 10}, {-170, 10}};
  EXPECT_DOUBLE_EQ(unwrap_longitudes(line, 4, false, WrapMode::automatic).vertices[3].lon, 190);
  const LonLat parallel[] = {{0, 10}, {180, 10}, {-180, 10}};
  EXPECT_DOUBLE_EQ(unwrap_longitudes(parallel, 3, false, WrapMode::automatic).vertices[2].lon, -180);
  // -wrap none reads every ring as written.
  const std::vector<LonLat> uncut = {{170, -20}, {-170, -20}, {-170, -10}, {170, -10}};
  std::vector<LonLat> closed = uncut;
  closed.push_back(uncut.front());
  EXPECT_TRUE(as_written(unwrap_longitudes(closed.data(), closed.size(), true, WrapMode::none), uncut));
}

}  // namespace
}  // namespace qtmv::sites
