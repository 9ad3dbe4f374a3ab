// The validity module: GEOS's reason and place for each kind of invalid polygon, the
// problems found before GEOS, MakeValid's result, the longitude axis and the +-180 test, and the
// reader's side (warnings capped, -strict, -makevalid, the summary).
#include "sites/polygon_validity.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::any_contains;
using test::make_dataset;
using test::options_at;
using test::temp_path;
using test::TestFeature;

std::unique_ptr<OGRGeometry> wkt(const std::string& text) {
  OGRGeometry* g = nullptr;
  if (OGRGeometryFactory::createFromWkt(text.c_str(), nullptr, &g) != OGRERR_NONE) throw std::runtime_error(text);
  return std::unique_ptr<OGRGeometry>(g);
}

std::string problem_of(const std::string& text) {
  const auto problem = find_polygon_problem(*wkt(text));
  return problem ? problem->describe() : "valid";
}

TEST(PolygonValidity, GeosIsThere) { ASSERT_TRUE(have_geos()) << "GDAL without GEOS: nothing below can pass"; }

TEST(PolygonValidity, EachKindGetsItsReasonAndPlace) {
  EXPECT_EQ(problem_of("POLYGON ((0 0,10 0,10 10,0 10,0 0),(20 20,25 20,25 25,20 25,20 20))"),
            "Hole lies outside shell at (20, 20)");
  EXPECT_EQ(problem_of("POLYGON ((0 0,10 10,10 0,0 10,0 0))"), "Self-intersection at (5, 5)");
  EXPECT_EQ(problem_of("POLYGON ((60 0,70 0,65 0,60 0))"), "Self-intersection at (65, 0)");
  EXPECT_EQ(problem_of("POLYGON ((0 0,20 0,20 20,0 20,0 0),(2 2,18 2,18 18,2 18,2 2),(5 5,15 5,15 15,5 15,5 5))"),
            "Holes are nested at (5, 5)");
  EXPECT_EQ(problem_of("MULTIPOLYGON (((0 0,10 0,10 10,0 10,0 0)),((5 5,15 5,15 15,5 15,5 5)))"),
            "Self-intersection at (10, 5)");
  EXPECT_EQ(problem_of("POLYGON ((0 0,10 0,10 10,5 10,5 20,5 10,0 10,0 0))"), "Ring Self-intersection at (5, 10)");
  // GEOS cannot take these two: found before it.
  EXPECT_EQ(problem_of("POLYGON ((100 0,110 0))"), "Too few points in ring at (100, 0)");
  EXPECT_EQ(problem_of("POLYGON ((0 0,10 0,10 10,0 10))"), "Ring not closed at (0, 10)");
  // An unclosed ring that is also a bow-tie: GEOS's reason, on the ring as it is read (closed).
  EXPECT_EQ(problem_of("POLYGON ((0 0,10 10,10 0,0 10))"), "Self-intersection at (5, 5)");
}

TEST(PolygonValidity, ValidShapesAndNonPolygonsHaveNoProblem) {
  EXPECT_EQ(problem_of("POLYGON ((0 0,0 0,10 0,10 0,10 10,0 10,0 0))"), "valid");  // duplicate vertices
  EXPECT_EQ(problem_of("MULTIPOLYGON (((0 0,1 0,1 1,0 0)),((1 1,2 1,2 2,1 1)))"), "valid");  // touching at a point
  EXPECT_EQ(problem_of("LINESTRING (0 0,10 10,10 0,0 10)"), "valid");  // lines cross as they like
  EXPECT_EQ(problem_of("POINT (1 2)"), "valid");
  EXPECT_EQ(problem_of("POLYGON EMPTY"), "valid");
  // Members of a collection may overlap; each is checked alone.
  EXPECT_EQ(problem_of("GEOMETRYCOLLECTION (POLYGON ((0 0,10 0,10 10,0 10,0 0)),POLYGON ((5 5,15 5,15 15,5 15,5 5)),"
                       "LINESTRING (0 0,1 1))"),
            "valid");
  EXPECT_EQ(problem_of("GEOMETRYCOLLECTION (POINT (0 0),POLYGON ((0 0,10 10,10 0,0 10,0 0)))"),
            "Self-intersection at (5, 5)");
}

TEST(PolygonValidity, MakeValidGivesGeosLinework) {
  std::string error;
  auto bow_tie = make_valid(*wkt("POLYGON ((0 0,10 10,10 0,0 10,0 0))"), error);
  ASSERT_TRUE(bow_tie) << error;
  EXPECT_EQ(describe_shape(*bow_tie), "MultiPolygon of 2 polygons");
  EXPECT_TRUE(bow_tie->IsValid());
  EXPECT_NEAR(bow_tie->toMultiPolygon()->get_Area(), 50.0, 1e-9);
  // The rings are closed first: an unclosed square becomes the square.
  auto square = make_valid(*wkt("POLYGON ((0 0,10 0,10 10,0 10))"), error);
  ASSERT_TRUE(square) << error;
  EXPECT_EQ(describe_shape(*square), "Polygon of 1 ring");
  EXPECT_NEAR(square->toPolygon()->get_Area(), 100.0, 1e-9);
  auto flat = make_valid(*wkt("POLYGON ((60 0,70 0,65 0,60 0))"), error);
  ASSERT_TRUE(flat) << error;
  EXPECT_EQ(describe_shape(*flat), "MultiLineString of 2 parts");
}

TEST(PolygonValidity, DescribeShape) {
  EXPECT_EQ(describe_shape(*wkt("POLYGON ((0 0,1 0,1 1,0 0),(0.1 0.05,0.2 0.05,0.2 0.1,0.1 0.05))")), "Polygon of 2 rings");
  EXPECT_EQ(describe_shape(*wkt("MULTIPOLYGON (((0 0,1 0,1 1,0 0)))")), "MultiPolygon of 1 polygon");
  EXPECT_EQ(describe_shape(*wkt("GEOMETRYCOLLECTION (POLYGON ((0 0,1 0,1 1,0 0)),LINESTRING (0 0,1 1))")),
            "GeometryCollection (Polygon of 1 ring, LineString)");
  EXPECT_EQ(describe_shape(*wkt("POLYGON EMPTY")), "an empty Polygon");
}

TEST(PolygonValidity, LongitudeAxisFollowsTheDataAxisOrder) {
  OGRSpatialReference srs;
  srs.importFromEPSG(4326);
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  EXPECT_EQ(longitude_axis(srs), 0);
  srs.SetAxisMappingStrategy(OAMS_AUTHORITY_COMPLIANT);  // lat, lon
  EXPECT_EQ(longitude_axis(srs), 1);
  OGRSpatialReference mercator;
  mercator.importFromEPSG(3857);
  EXPECT_EQ(longitude_axis(mercator), -1);
}

TEST(PolygonValidity, RingsAcrossTheAntimeridian) {
  const auto fiji = wkt("POLYGON ((170 0,-170 0,-170 10,-175 10,175 5,170 10,170 0))");
  EXPECT_TRUE(ring_crosses_antimeridian(*fiji, 0, 180.0));
  EXPECT_FALSE(ring_crosses_antimeridian(*fiji, 1, 180.0));
  EXPECT_FALSE(ring_crosses_antimeridian(*wkt("POLYGON ((-170 -80,0 -80,170 -80,170 80,0 80,-170 80,-170 -80))"), 0, 180.0));
  EXPECT_TRUE(find_polygon_problem(*fiji).has_value());  // flat, it is self-intersecting
}

// The reader's side, through read_sites.
std::string dataset_of(const std::vector<std::string>& wkts, const std::string& srs = "EPSG:4326") {
  std::vector<TestFeature> features;
  for (std::size_t k = 0; k < wkts.size(); ++k) features.push_back({wkts[k], "f" + std::to_string(k)});
  return make_dataset(temp_path("v.gpkg"), "GPKG", "v", srs, features);
}

TEST(PolygonValidityCheck, WarnsByFidCountsAndCapsTheLines) {
  std::vector<std::string> wkts;
  for (int k = 0; k < 23; ++k) {
    const int x = -170 + 15 * k;
    wkts.push_back("POLYGON ((" + std::to_string(x) + " 0," + std::to_string(x + 10) + " 10," + std::to_string(x + 10) +
                   " 0," + std::to_string(x) + " 10," + std::to_string(x) + " 0))");
  }
  wkts.push_back("POLYGON ((0 -50,10 -50,10 -40,0 -40,0 -50))");  // valid
  const std::string path = dataset_of(wkts);
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(4, &messages));
  EXPECT_EQ(set.summary.sites, 24u);
  EXPECT_EQ(set.summary.invalid_polygons, 23u);
  EXPECT_EQ(set.summary.repaired_polygons, 0u);
  const std::string at = "'" + path + "', layer 'v', FID ";
  EXPECT_TRUE(any_contains(messages, at + "1: invalid polygon (Self-intersection at (-165, 5)); read by even-odd over "
                                          "all rings (-makevalid repairs it)"));
  EXPECT_TRUE(any_contains(messages, at + "20: invalid polygon"));
  EXPECT_FALSE(any_contains(messages, at + "21: invalid polygon"));
  EXPECT_FALSE(any_contains(messages, at + "24: invalid polygon"));
  EXPECT_TRUE(any_contains(messages, "'" + path + "', layer 'v': 3 more invalid polygon(s) not listed (23 in all)"));
  EXPECT_TRUE(any_contains(messages, "24 sites, ") && any_contains(messages, "; 23 invalid polygon(s) (read by even-odd)"));
}

// Features are examined on all threads in blocks of up to 1024: the warnings still come in
// feature order, the same with one thread as with several, and -strict stops at the first.
TEST(PolygonValidityCheck, WarningsComeInFeatureOrderWhateverTheThreads) {
  std::vector<std::string> wkts;
  for (int k = 0; k < 2600; ++k) {
    const double x = -170.0 + 0.1 * (k % 3000), y = -60.0 + 0.04 * k;
    const std::string a = std::to_string(x), b = std::to_string(x + 0.05), c = std::to_string(y),
                      d = std::to_string(y + 0.05);
    if (k % 97 == 5) {
      wkts.push_back("POLYGON ((" + a + " " + c + "," + b + " " + d + "," + b + " " + c + "," + a + " " + d + "," + a +
                     " " + c + "))");  // a bow-tie
    } else if (k % 211 == 7) {
      wkts.push_back("POINT (" + a + " 1000)");  // beyond +-540 degrees
    } else if (k % 389 == 3) {
      wkts.push_back("POLYGON EMPTY");
    } else {
      wkts.push_back("POLYGON ((" + a + " " + c + "," + b + " " + c + "," + b + " " + d + "," + a + " " + c + "))");
    }
  }
  const std::string path = dataset_of(wkts);
  std::vector<std::string> messages[2];
  for (int k = 0; k < 2; ++k) {
    ReadOptions o = options_at(4, &messages[k]);
    o.threads = k == 0 ? 1 : 4;
    const SiteSet set = read_sites(path, o);
    EXPECT_EQ(set.summary.invalid_polygons, 27u);
    EXPECT_EQ(set.summary.skipped_coordinate, 13u);
    EXPECT_EQ(set.summary.skipped_empty, 6u);
  }
  EXPECT_EQ(messages[0], messages[1]);
  ASSERT_GE(messages[0].size(), 3u);
  const std::string at = "'" + path + "', layer 'v', FID ";
  EXPECT_NE(messages[0][0].find(at + "4: empty geometry"), std::string::npos) << messages[0][0];
  EXPECT_NE(messages[0][1].find(at + "6: invalid polygon"), std::string::npos) << messages[0][1];
  EXPECT_NE(messages[0][2].find(at + "8: coordinate"), std::string::npos) << messages[0][2];
  ReadOptions strict = options_at(4, nullptr);
  strict.strict = true;
  strict.threads = 4;
  try {
    read_sites(path, strict);
    FAIL() << "no error under -strict";
  } catch (const ReadError& e) {
    EXPECT_NE(std::string(e.what()).find(at + "4: empty geometry"), std::string::npos) << e.what();
  }
}

TEST(PolygonValidityCheck, StrictFailsAndMakeValidRepairs) {
  const std::string path = dataset_of({"POINT (50 50)", "POLYGON ((0 0,10 10,10 0,0 10,0 0))"});
  ReadOptions strict = options_at(4, nullptr);
  strict.strict = true;
  try {
    read_sites(path, strict);
    FAIL() << "no error under -strict";
  } catch (const ReadError& e) {
    EXPECT_EQ(std::string(e.what()), "'" + path + "', layer 'v', FID 2: invalid polygon (Self-intersection at (5, 5)) "
                                                  "(-strict; -makevalid repairs it)");
  }
  std::vector<std::string> messages;
  ReadOptions repair = options_at(6, &messages);
  repair.make_valid = true;
  repair.strict = true;  // a repaired polygon is no error
  const SiteSet repaired = read_sites(path, repair);
  EXPECT_EQ(repaired.summary.invalid_polygons, 1u);
  EXPECT_EQ(repaired.summary.repaired_polygons, 1u);
  EXPECT_TRUE(any_contains(messages, "FID 2: invalid polygon (Self-intersection at (5, 5)); repaired by -makevalid: "
                                     "Polygon of 1 ring became MultiPolygon of 2 polygons"));
  EXPECT_TRUE(any_contains(messages, "1 invalid polygon(s) (1 repaired by -makevalid)"));
  // The two triangles fill what even-odd fills.
  const SiteSet plain = read_sites(path, options_at(6, nullptr));
  EXPECT_EQ(test::fixed_cells_by_site(repaired.geometry), test::fixed_cells_by_site(plain.geometry));
  EXPECT_FALSE(test::fixed_cells_by_site(plain.geometry)[1].empty());
}

TEST(PolygonValidityCheck, AntimeridianRingsAreLeftAloneUnderWrapAutoOnly) {
  const std::string path = dataset_of({"POLYGON ((170 0,-170 0,-170 10,-175 10,175 5,170 10,170 0))"});
  std::vector<std::string> messages;
  EXPECT_EQ(read_sites(path, options_at(4, &messages)).summary.invalid_polygons, 0u);
  EXPECT_FALSE(any_contains(messages, "invalid polygon"));
  ReadOptions flat = options_at(4, &messages);
  flat.wrap = WrapMode::none;
  EXPECT_EQ(read_sites(path, flat).summary.invalid_polygons, 1u);
  EXPECT_TRUE(any_contains(messages, "FID 1: invalid polygon (Self-intersection"));
}

}  // namespace
}  // namespace qtmv::sites
