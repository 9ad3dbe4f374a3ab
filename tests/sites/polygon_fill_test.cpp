// Polygon fill against GEOS: the fixed cells are the cells whose centres GEOS puts inside the
// polygon in flat lon/lat; rings across +-180 and round a pole give the cells of the same region
// written without crossing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <cstdio>
#include <set>
#include <vector>

#include "sites/site_builder.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using grid::LonLat;
using test::from_wkt;
using test::geos_inside;

std::string fmt(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", x);
  return buffer;
}

/// Fixed cells of a polygon (rings in lon/lat) through the builder.
std::set<grid::Code> filled(const std::vector<LonLatPath>& rings, int level, WrapMode wrap = WrapMode::automatic,
                            EdgeShape edges = EdgeShape::lonlat) {
  SiteBuilder b(level, edges, wrap);
  b.begin_site();
  b.add_polygon(rings);
  b.end_site();
  std::set<grid::Code> out;
  for (const auto& f : b.geometry().fixed_cells) {
    EXPECT_TRUE(out.insert(f.code).second) << "cell " << f.code << " twice";
  }
  // The cover's nodes and cells hold each cell once.
  std::size_t node_cells = 0;
  for (const auto& n : b.geometry().fixed_nodes) node_cells += std::size_t{1} << (2 * (level - n.level));
  const std::set<grid::Code> all = test::fixed_cells_by_site(b.geometry())[0];
  EXPECT_EQ(all.size(), out.size() + node_cells);
  return all;
}

std::vector<LonLatPath> rings_of(const OGRGeometry& g) {
  std::vector<LonLatPath> out;
  const OGRPolygon& p = *g.toPolygon();
  auto ring = [](const OGRLinearRing& r) {
    LonLatPath path;
    for (int k = 0; k < r.getNumPoints(); ++k) path.push_back({r.getX(k), r.getY(k)});
    return path;
  };
  out.push_back(ring(*p.getExteriorRing()));
  for (int k = 0; k < p.getNumInteriorRings(); ++k) out.push_back(ring(*p.getInteriorRing(k)));
  return out;
}

TEST(PolygonFill, EqualsGeosForPolygonsThatDoNotCrossTheAntimeridian) {
  // A star round a point on the octant corner, a thin sliver, a polygon with a hole, one across
  // the equator and the lon 0 and 90 meridians.
  std::string star = "POLYGON((";
  for (int k = 0; k <= 14; ++k) {
    const double a = (k % 14) * 2 * M_PI / 14, r = (k % 2) ? 9 : 23;
    star += std::to_string(90 + r * std::cos(a)) + " " + std::to_string(0 + 0.8 * r * std::sin(a)) + (k < 14 ? "," : "))");
  }
  const std::vector<std::string> wkts = {
      star,
      "POLYGON((-30 10,40 10.5,40 11.2,-30 10))",
      "POLYGON((-20 -40,60 -40,60 40,-20 40,-20 -40),(0 -20,40 -20,40 20,0 20,0 -20))",
      "POLYGON((-100 -60,-10 -5,80 70,170 -80,35 -75,-100 -60))",
  };
  for (int level : {3, 6}) {
    for (const auto& wkt : wkts) {
      const auto g = from_wkt(wkt);
      EXPECT_EQ(filled(rings_of(*g), level), geos_inside(*g, level)) << wkt << " level " << level;
    }
  }
}

TEST(PolygonFill, BandsRoundTheGlobeCutAtTheAntimeridianEqualGeos) {
  // Edges from -180 to +180 along a parallel: cut data spanning every longitude. Read as seams
  // they would collapse the band to a line (and invert it when it has a hole). (Other edges
  // longer than 180 degrees are joined the short way by the -wrap auto rule, as the issue says.)
  const std::vector<std::string> wkts = {
      "POLYGON((-180 -60,180 -60,180 60,-180 60,-180 -60))",
      "POLYGON((-180 -60,180 -60,180 60,-180 60,-180 -60),(-10 12,30 12,30 40,-10 40,-10 12))",
  };
  for (int level : {3, 6}) {
    for (const auto& wkt : wkts) {
      const auto g = from_wkt(wkt);
      const auto cells = filled(rings_of(*g), level);
      EXPECT_EQ(cells, geos_inside(*g, level)) << wkt << " level " << level;
      EXPECT_EQ(cells, filled(rings_of(*g), level, WrapMode::none)) << wkt << " level " << level;
    }
  }
}

TEST(PolygonFill, HoleWithAnotherPolygonInside) {
  // Site 0: a square with a hole; site 1: an island inside the hole. Each gets its own cells.
  const int level = 6;
  SiteBuilder b(level, EdgeShape::lonlat, WrapMode::automatic);
  const auto outer = from_wkt("POLYGON((10 10,50 10,50 50,10 50,10 10),(20 20,40 20,40 40,20 40,20 20))");
  const auto island = from_wkt("POLYGON((25 25,35 25,35 35,25 35,25 25))");
  b.begin_site();
  b.add_polygon(rings_of(*outer));
  b.end_site();
  b.begin_site();
  b.add_polygon(rings_of(*island));
  b.end_site();
  const auto by_site = test::fixed_cells_by_site(b.geometry());
  EXPECT_EQ(by_site[0], geos_inside(*outer, level));
  EXPECT_EQ(by_site[1], geos_inside(*island, level));
  for (grid::Code c : by_site[1]) EXPECT_FALSE(by_site[0].count(c));
}

TEST(PolygonFill, RingAcrossTheAntimeridianEqualsItsTwoHalves) {
  const int level = 6;
  // Crossing +-180 without a cut, as GeoJSON sources write it.
  const std::vector<LonLatPath> crossing = {{{170, -10}, {-165, -12}, {-170, 25}, {175, 20}, {170, -10}}};
  // Reference: the polygon with continuous longitudes, tested on centres moved to [0, 360).
  const auto west = from_wkt("POLYGON((170 -10,195 -12,190 25,175 20,170 -10))");
  std::set<grid::Code> expected_west;
  OGRPreparedGeometryH prepared = OGRCreatePreparedGeometry(OGRGeometry::ToHandle(west.get()));
  for (grid::Code code = 0; code < grid::cell_count(level); ++code) {
    const LonLat c = grid::cell_centre(code, level);
    OGRPoint p(c.lon < 0 ? c.lon + 360 : c.lon, c.lat);
    if (OGRPreparedGeometryContains(prepared, OGRGeometry::ToHandle(&p))) expected_west.insert(code);
  }
  OGRDestroyPreparedGeometry(prepared);
  EXPECT_EQ(filled(crossing, level), expected_west);
  EXPECT_FALSE(expected_west.empty());
  // Read flat (-wrap none), the ring covers the other side of the globe instead.
  const std::set<grid::Code> flat = filled(crossing, level, WrapMode::none);
  EXPECT_GT(flat.size(), 10 * expected_west.size());
}

TEST(PolygonFill, RingsRoundAPoleEncloseIt) {
  const int level = 6;
  for (double lat : {72.5, -66.0}) {
    // Winds once round the globe without a vertex at the pole.
    LonLatPath cap;
    for (int lon = -180; lon < 180; lon += 15) cap.push_back({double(lon), lat + 3 * std::sin(lon * M_PI / 60)});
    cap.push_back(cap.front());
    // Reference: the same cap in flat lon/lat, closed through the pole.
    std::string wkt = "POLYGON((";
    for (std::size_t k = 0; k + 1 < cap.size(); ++k) wkt += fmt(cap[k].lon) + " " + fmt(cap[k].lat) + ",";
    const double pole = lat > 0 ? 90 : -90;
    wkt += "180 " + fmt(cap.front().lat) + ",180 " + fmt(pole) + ",-180 " + fmt(pole) + "," + fmt(cap.front().lon) +
           " " + fmt(cap.front().lat) + "))";
    const auto reference = from_wkt(wkt);
    const auto expected = geos_inside(*reference, level);
    EXPECT_EQ(filled({cap}, level), expected) << lat;
    // Reversed orientation: the same cells.
    LonLatPath reversed(cap.rbegin(), cap.rend());
    EXPECT_EQ(filled({reversed}, level), expected) << lat;
    // As world-atlas writes Antarctica: from -180 to +180, closed by a seam edge.
    LonLatPath seam;
    for (int lon = -180; lon <= 180; lon += 15) seam.push_back({double(lon), lat + 3 * std::sin(lon * M_PI / 60)});
    seam.push_back(seam.front());
    EXPECT_EQ(filled({seam}, level), expected) << lat;
  }
}

TEST(PolygonFill, GeodesicEdgesStayCloseToLonLatOnesForSmallPolygons) {
  const int level = 8;
  const std::vector<LonLatPath> rings = {{{10, 10}, {11, 10}, {11, 11}, {10, 11}, {10, 10}}};
  const auto lonlat = filled(rings, level);
  const auto geodesic = filled(rings, level, WrapMode::automatic, EdgeShape::geodesic);
  std::vector<grid::Code> diff;
  std::set_symmetric_difference(lonlat.begin(), lonlat.end(), geodesic.begin(), geodesic.end(), std::back_inserter(diff));
  EXPECT_LT(diff.size(), lonlat.size() / 10);
  EXPECT_GT(geodesic.size(), 0u);
}

}  // namespace
}  // namespace qtmv::sites

namespace qtmv::sites {
namespace {

/// fill()'s cells, and cover()'s nodes and cells expanded, as sets (each cell once in the cover).
std::pair<std::set<grid::Code>, std::set<grid::Code>> fill_and_cover(const PolygonFiller& filler,
                                                                     const std::vector<FillRing>& rings) {
  std::vector<grid::Code> cells;
  filler.fill(rings, cells);
  const std::set<grid::Code> filled(cells.begin(), cells.end());
  std::vector<grid::Code> cover_cells;
  std::vector<PolygonFiller::CoverNode> nodes;
  filler.cover(rings, cover_cells, nodes);
  std::set<grid::Code> covered;
  std::size_t count = cover_cells.size();
  for (grid::Code c : cover_cells) covered.insert(c);
  for (const auto& n : nodes) {
    EXPECT_LT(n.level, filler.level());
    const int k = filler.level() - n.level;
    count += std::size_t{1} << (2 * k);
    for (std::uint64_t r = 0; r < (std::uint64_t{1} << k); ++r) {
      const grid::RowCodes row = grid::row_codes_below(grid::cell_of(n.code, n.level), k, r, filler.level());
      for (grid::Code code = row.first; code <= row.last; ++code) covered.insert(code);
    }
  }
  EXPECT_EQ(count, covered.size()) << "a cell twice in the cover";
  return {filled, covered};
}

// The cover holds exactly fill()'s cells, for random star-shaped rings with holes (some across
// +-180, some round a pole), at every level up to 9; and it is made of far fewer entries.
TEST(PolygonCover, HoldsExactlyTheFilledCells) {
  std::mt19937_64 rng(1515);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto star = [&](double lon, double lat, double radius, int n, bool reverse) {
    FillRing ring;
    for (int k = 0; k <= n; ++k) {
      const int kk = k % n;
      const double angle = 2 * M_PI * (reverse ? n - kk : kk) / n;
      const double r = radius * (0.5 + 0.5 * unit(rng));
      ring.vertices.push_back({lon + r * std::cos(angle), std::clamp(lat + 0.5 * r * std::sin(angle), -89.9, 89.9)});
    }
    ring.vertices.back() = ring.vertices.front();
    return ring;
  };
  std::size_t entries = 0, cells = 0;
  for (int level = 1; level <= 9; ++level) {
    const PolygonFiller filler(level);
    for (int trial = 0; trial < 12; ++trial) {
      std::vector<FillRing> rings;
      const double lon = -200 + 400 * unit(rng), lat = -70 + 140 * unit(rng), radius = 5 + 60 * unit(rng);
      rings.push_back(star(lon, lat, radius, 5 + static_cast<int>(unit(rng) * 40), false));
      if (trial % 3 == 0) rings.push_back(star(lon, lat, radius / 3, 7, true));  // a hole
      if (trial % 4 == 1) {                                                   // a cap round a pole
        FillRing cap;
        const double cap_lat = trial % 8 == 1 ? 70 - 10 * unit(rng) : -75 + 10 * unit(rng);
        for (int k = 0; k <= 36; ++k) cap.vertices.push_back({-180.0 + 10.0 * k, cap_lat + 3 * unit(rng)});
        cap.vertices.back().lat = cap.vertices.front().lat;
        cap.winding = 1;
        rings.push_back(cap);
      }
      const auto [filled, covered] = fill_and_cover(filler, rings);
      ASSERT_EQ(filled, covered) << "level " << level << " trial " << trial;
      if (level == 9) {
        std::vector<grid::Code> c;
        std::vector<PolygonFiller::CoverNode> n;
        filler.cover(rings, c, n);
        entries += c.size() + n.size();
        cells += filled.size();
      }
    }
  }
  EXPECT_LT(entries * 4, cells);
}

// A polygon of thousands of inside intervals is covered in tasks below level 4 (other threads of
// a team take them): the same entries in the same order with one thread as with four, and
// exactly fill()'s cells.
TEST(PolygonCover, LargePolygonsCoveredInTasksGiveTheSameEntriesWhateverTheThreads) {
  const PolygonFiller filler(11);
  std::vector<FillRing> rings(2);
  for (int k = 0; k <= 400; ++k) {  // a band from 60 S to 60 N, its sides wavy
    const double t = k / 400.0;
    rings[0].vertices.push_back({10.0 + 3.0 * std::sin(40 * t), -60.0 + 120.0 * t});
  }
  for (int k = 0; k <= 400; ++k) {
    const double t = k / 400.0;
    rings[0].vertices.push_back({30.0 + 2.0 * std::cos(30 * t), 60.0 - 120.0 * t});
  }
  rings[0].vertices.push_back(rings[0].vertices.front());
  rings[1].vertices = {{18, -10}, {22, -10}, {22, 10}, {18, 10}, {18, -10}};  // a hole
  std::vector<grid::Code> cells[2];
  std::vector<PolygonFiller::CoverNode> nodes[2];
  filler.cover(rings, cells[0], nodes[0]);
#ifdef _OPENMP
#pragma omp parallel num_threads(4)
#pragma omp single
#endif
  filler.cover(rings, cells[1], nodes[1]);
  EXPECT_EQ(cells[0], cells[1]);
  ASSERT_EQ(nodes[0].size(), nodes[1].size());
  for (std::size_t k = 0; k < nodes[0].size(); ++k) {
    ASSERT_EQ(nodes[0][k].code, nodes[1][k].code) << k;
    ASSERT_EQ(nodes[0][k].level, nodes[1][k].level) << k;
  }
  const auto [filled, covered] = fill_and_cover(filler, rings);
  EXPECT_EQ(filled, covered);
  EXPECT_GT(filled.size(), 500000u);
}

}  // namespace
}  // namespace qtmv::sites
