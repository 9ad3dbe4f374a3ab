// Polygon fill against GEOS: the fixed cells are the cells whose centres GEOS puts inside the
// polygon in flat lon/lat; rings across +-180 and round a pole give the cells of the same region
// written without crossing.
#include <gtest/gtest.h>

#include <cmath>
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
  return out;
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
