// The OGR reader on data made here through the GDAL API: points at the poles, on +-180 and on
// octant edges; lines and polygons; multi-geometries; CRS handling; bad input and its messages.
#include <gtest/gtest.h>

#include <algorithm>

#include <cpl_conv.h>
#include <cpl_vsi.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

#include "sites/ogr_site_reader.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::any_contains;
using test::corrupt_geometry;
using test::make_dataset;
using test::options_at;
using test::temp_path;
using test::TestFeature;

TEST(OgrSiteReader, PointsAtPolesAntimeridianAndOctantEdges) {
  const std::vector<std::pair<double, double>> points = {
      {0, 90}, {123, -90}, {180, 10}, {-180, -10}, {0, 0}, {90, 0}, {-90, 45}, {45, 0}, {179.999999, 89.5}, {-0.0, -33}};
  std::vector<TestFeature> features;
  for (std::size_t k = 0; k < points.size(); ++k) {
    char wkt[96];
    std::snprintf(wkt, sizeof wkt, "POINT (%.17g %.17g)", points[k].first, points[k].second);
    features.push_back({wkt, "p" + std::to_string(k)});
  }
  const std::string path = make_dataset(temp_path("points.gpkg"), "GPKG", "points", "EPSG:4326", features);
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(10, &messages));
  ASSERT_EQ(set.geometry.site_count, static_cast<int>(points.size()));
  ASSERT_EQ(set.table.sites.size(), points.size());
  EXPECT_EQ(set.geometry.pieces.size(), points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& piece = set.geometry.pieces[k];
    const grid::Vec3 expected = grid::unit_vector(points[k].first, points[k].second);
    EXPECT_EQ(piece.site, static_cast<int>(k));
    EXPECT_DOUBLE_EQ(piece.a.x, expected.x);
    EXPECT_DOUBLE_EQ(piece.a.z, expected.z);
    EXPECT_EQ(set.table.sites[k].fid, static_cast<std::int64_t>(k + 1));  // GPKG FIDs start at 1
    EXPECT_STREQ(set.table.sites[k].attributes->GetFieldAsString("name"), ("p" + std::to_string(k)).c_str());
    EXPECT_EQ(set.table.sites[k].site_cells, 1u);
    EXPECT_EQ(set.table.sites[k].kind, unsigned(kPointSite));
  }
  const auto cells = test::site_cells_by_site(set.geometry);
  for (std::size_t k = 0; k < points.size(); ++k) {
    EXPECT_EQ(*cells[k].begin(), grid::lonlat_to_code(points[k].first, points[k].second, 10)) << k;
  }
  EXPECT_TRUE(set.geometry.fixed_cells.empty());
  EXPECT_EQ(set.summary.skipped, 0u);
  EXPECT_NE(set.table.definition(), nullptr);
}

TEST(OgrSiteReader, MultiGeometriesCollectionsAndCurvesAreOneSiteEach) {
  const std::string path = make_dataset(
      temp_path("multi.gpkg"), "GPKG", "things", "EPSG:4326",
      {{"MULTIPOINT ((1 1),(50 50))", "mp"},
       {"MULTILINESTRING ((0 0,10 10),(20 0,30 -10))", "ml"},
       {"MULTIPOLYGON (((0 0,10 0,10 10,0 10,0 0)),((20 20,30 20,30 30,20 30,20 20)))", "mpoly"},
       {"GEOMETRYCOLLECTION (POINT (-40 -40),LINESTRING (-50 -50,-60 -55),POLYGON ((-70 10,-60 10,-60 20,-70 10)))", "gc"},
       {"CIRCULARSTRING (0 -30,10 -20,20 -30)", "arc"},
       {"POINT Z (5 5 100)", "z"}});
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(7, &messages));
  ASSERT_EQ(set.geometry.site_count, 6);
  EXPECT_EQ(set.table.sites[0].kind, unsigned(kPointSite));
  EXPECT_EQ(set.table.sites[0].site_cells, 2u);
  EXPECT_EQ(set.table.sites[1].kind, unsigned(kLineSite));
  EXPECT_EQ(set.table.sites[2].kind, unsigned(kPolygonSite));
  EXPECT_GT(set.table.sites[2].fixed_cells, 0u);
  EXPECT_EQ(set.table.sites[3].kind, unsigned(kPointSite | kLineSite | kPolygonSite));
  EXPECT_EQ(set.table.sites[4].kind, unsigned(kLineSite));
  // The linearised arc bulges north of its chord to lat -20.
  double max_lat = -90;
  for (const auto& p : set.geometry.pieces) {
    if (p.site == 4) max_lat = std::max(max_lat, std::asin(p.a.z) / grid::kDegree);
  }
  EXPECT_NEAR(max_lat, -20, 0.1);
  // Every site cell points at pieces of its own site.
  for (const auto& c : set.geometry.site_cells) {
    ASSERT_LT(c.piece_begin, c.piece_end);
    for (auto p = c.piece_begin; p < c.piece_end; ++p) EXPECT_EQ(set.geometry.pieces[p].site, c.site);
  }
}

TEST(OgrSiteReader, LinesAcrossTheAntimeridianAndOverAPoleFromAZippedShapefile) {
  // A shapefile inside a zip, read through /vsizip/.
  const std::string zip = temp_path("lines.zip"), shp = temp_path("lines");
  make_dataset(shp + ".shp", "ESRI Shapefile", "lines", "EPSG:4326",
               {{"LINESTRING (170 60,-170 65)", "across"}, {"LINESTRING (-30 80,150 80)", "over the pole"}});
  for (const char* ext : {".shp", ".shx", ".dbf", ".prj"}) {
    ASSERT_EQ(CPLCopyFile(("/vsizip/" + zip + "/lines" + ext).c_str(), (shp + ext).c_str()), 0) << ext;
  }
  ReadOptions o = options_at(6, nullptr);
  const SiteSet flat_lonlat = read_sites("/vsizip/" + zip + "/lines.shp", o);
  ASSERT_EQ(flat_lonlat.geometry.site_count, 2);
  auto lon_range = [](const std::set<grid::Code>& cells, int level) {
    double lo = 180, hi = -180, lat_max = -90;
    for (grid::Code c : cells) {
      const grid::LonLat p = grid::cell_centre(c, level);
      lo = std::min(lo, p.lon);
      hi = std::max(hi, p.lon);
      lat_max = std::max(lat_max, p.lat);
    }
    return std::vector<double>{lo, hi, lat_max};
  };
  auto cells = test::site_cells_by_site(flat_lonlat.geometry);
  // -wrap auto: the short way across +-180, nowhere near lon 0.
  for (grid::Code c : cells[0]) EXPECT_GT(std::abs(grid::cell_centre(c, 6).lon), 165.0);
  // -edges lonlat: along the parallel 80, not over the pole.
  EXPECT_LT(lon_range(cells[1], 6)[2], 81.0);
  // -edges geodesic: over the pole.
  o.edges = EdgeShape::geodesic;
  cells = test::site_cells_by_site(read_sites("/vsizip/" + zip + "/lines.shp", o).geometry);
  EXPECT_GT(lon_range(cells[1], 6)[2], 89.0);
  for (grid::Code c : cells[0]) EXPECT_GT(std::abs(grid::cell_centre(c, 6).lon), 165.0);
  // -wrap none: the long way, across lon 0.
  o.edges = EdgeShape::lonlat;
  o.wrap = WrapMode::none;
  cells = test::site_cells_by_site(read_sites("/vsizip/" + zip + "/lines.shp", o).geometry);
  EXPECT_LT(lon_range(cells[0], 6)[0], -160.0);
  EXPECT_TRUE(cells[0].count(grid::lonlat_to_code(0, 62.5, 6)));
}

TEST(OgrSiteReader, ProjectedCrsIsTransformedToLonLat) {
  // Web Mercator coordinates of known points: x = R lon, y = R ln tan(pi/4 + lat/2).
  const double R = 6378137.0;
  auto mercator = [&](double lon, double lat) {
    char wkt[96];
    std::snprintf(wkt, sizeof wkt, "POINT (%.17g %.17g)", R * lon * M_PI / 180,
                  R * std::log(std::tan(M_PI / 4 + lat * M_PI / 360)));
    return std::string(wkt);
  };
  const std::string path = make_dataset(temp_path("merc.gpkg"), "GPKG", "merc", "EPSG:3857",
                                        {{mercator(12.3, 45.6), "a"}, {mercator(-170.25, -60.5), "b"}});
  const SiteSet set = read_sites(path, options_at(12, nullptr));
  const auto cells = test::site_cells_by_site(set.geometry);
  EXPECT_EQ(*cells[0].begin(), grid::lonlat_to_code(12.3, 45.6, 12));
  EXPECT_EQ(*cells[1].begin(), grid::lonlat_to_code(-170.25, -60.5, 12));
  EXPECT_NEAR(set.geometry.pieces[0].a.z, std::sin(45.6 * grid::kDegree), 1e-12);
}

TEST(OgrSiteReader, ShapefileWithoutPrjIsTakenAsWgs84WithOneWarning) {
  const std::string dir = temp_path("noprj");
  const std::string path = make_dataset(dir + ".shp", "ESRI Shapefile", "noprj", "",
                                        {{"POINT (10 20)", "a"}, {"POINT (-30 40)", "b"}});
  VSIUnlink((dir + ".prj").c_str());
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(5, &messages));
  EXPECT_EQ(set.geometry.site_count, 2);
  int crs_warnings = 0;
  for (const auto& m : messages) crs_warnings += m.find("no CRS") != std::string::npos;
  EXPECT_EQ(crs_warnings, 1);
  EXPECT_EQ(set.table.sites[0].fid, 0);  // shapefile FIDs start at 0
  // -s_srs overrides: the same numbers read as Web Mercator metres land near (0, 0).
  ReadOptions o = options_at(5, nullptr);
  o.source_srs = "EPSG:3857";
  const SiteSet merc = read_sites(path, o);
  EXPECT_EQ(test::site_cells_by_site(merc.geometry)[0].count(grid::lonlat_to_code(0.0001, 0.0002, 5)), 1u);
}

TEST(OgrSiteReader, LayerWhereSqlAndClaims) {
  const std::string path = temp_path("two.gpkg");
  make_dataset(path, "GPKG", "first", "EPSG:4326", {{"POINT (1 1)", "x"}});
  {
    GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE));
    OGRSpatialReference srs;
    srs.importFromEPSG(4326);
    OGRLayer* layer = ds->CreateLayer("second", &srs, wkbUnknown, nullptr);
    OGRFieldDefn field("name", OFTString);
    layer->CreateField(&field);
    for (const char* wkt : {"POLYGON ((0 0,20 0,20 20,0 20,0 0))", "POLYGON ((10 10,30 10,30 30,10 30,10 10))",
                            "POINT (5 5)", "POINT (5.0000001 5.0000001)", "POINT (-100 -10)"}) {
      OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
      f->SetField("name", wkt);
      OGRGeometry* g = nullptr;
      OGRGeometryFactory::createFromWkt(wkt, nullptr, &g);
      f->SetGeometryDirectly(g);
      ASSERT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE) << wkt;
    }
  }
  std::vector<std::string> messages;
  ReadOptions o = options_at(6, &messages);
  o.layers = {"second"};
  o.distance = DistanceRule::cell;
  SiteSet set = read_sites(path, o);
  ASSERT_EQ(set.geometry.site_count, 5);
  // Overlapping polygons: both claim the overlap (as cells or nodes), the lower id holds it.
  const auto fixed = test::fixed_cells_by_site(set.geometry);
  const grid::Code in_overlap = grid::lonlat_to_code(15, 15, 6);
  EXPECT_TRUE(fixed[0].count(in_overlap));
  std::uint64_t overlap = 0;
  for (const grid::Code c : fixed[1]) overlap += fixed[0].count(c);
  EXPECT_GT(overlap, 0u);
  EXPECT_EQ(set.table.sites[0].fixed_cells, fixed[0].size());
  EXPECT_EQ(set.table.sites[1].fixed_cells, fixed[1].size() - overlap);
  // Two points in one cell under the cell rule: the lower id keeps it; both points lie inside
  // polygon 0, so neither has a cell of its own; a warning names them.
  EXPECT_FALSE(set.table.sites[2].has_own_cell);
  EXPECT_FALSE(set.table.sites[3].has_own_cell);
  EXPECT_EQ(set.table.sites[3].site_cells, 0u);
  EXPECT_TRUE(set.table.sites[4].has_own_cell);
  EXPECT_EQ(set.summary.sites_without_own_cell, 2u);
  EXPECT_TRUE(any_contains(messages, "2 site(s) have no cell of their own at level 6 (FIDs 3, 4)"));
  // The exact rule keeps both points' site cells.
  o.distance = DistanceRule::exact;
  set = read_sites(path, o);
  EXPECT_EQ(set.table.sites[3].site_cells, 1u);
  // -where and -sql.
  o.where = "name LIKE 'POINT%'";
  EXPECT_EQ(read_sites(path, o).geometry.site_count, 3);
  o.where.clear();
  o.sql = "SELECT * FROM second WHERE name LIKE 'POLYGON%'";
  EXPECT_EQ(read_sites(path, o).geometry.site_count, 2);
  o.dialect = "SQLITE";
  o.sql = "SELECT name, geom FROM second WHERE name LIKE 'POINT (5%'";
  EXPECT_EQ(read_sites(path, o).geometry.site_count, 2);
}

TEST(OgrSiteReader, ProgressIsReportedAndCanStop) {
  std::vector<TestFeature> features;
  for (int k = 0; k < 600; ++k) features.push_back({"POINT (" + std::to_string(k % 360 - 180) + " 1)", ""});
  const std::string path = make_dataset(temp_path("many.gpkg"), "GPKG", "many", "EPSG:4326", features);
  ReadOptions o = options_at(4, nullptr);
  std::vector<double> fractions;
  o.progress = [&](double f, const char*) {
    fractions.push_back(f);
    return true;
  };
  read_sites(path, o);
  ASSERT_GE(fractions.size(), 3u);
  EXPECT_EQ(fractions.front(), 0.0);
  EXPECT_EQ(fractions.back(), 1.0);
  o.progress = [](double f, const char*) { return f < 0.3; };
  EXPECT_THROW(read_sites(path, o), Interrupted);  // a stop, not a reading error
}

// --- bad input --------------------------------------------------------------------------------------

std::string error_of(const std::string& path, const ReadOptions& o) {
  try {
    read_sites(path, o);
  } catch (const ReadError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(OgrSiteReaderBadInput, MissingUnreadableFileLayerWhereSql) {
  const ReadOptions o = options_at(4, nullptr);
  EXPECT_EQ(error_of("/nonexistent/dir/cities.gpkg", o), "cannot open '/nonexistent/dir/cities.gpkg': no such file");
  const std::string text = temp_path("notes.txt");
  std::ofstream(text) << "not a vector dataset\n";
  EXPECT_NE(error_of(text, o).find("cannot open '" + text + "' as a vector dataset"), std::string::npos);

  const std::string path = make_dataset(temp_path("ok.gpkg"), "GPKG", "cities", "EPSG:4326", {{"POINT (1 2)", "a"}});
  ReadOptions bad = o;
  bad.layers = {"towns"};
  EXPECT_EQ(error_of(path, bad), "'" + path + "' has no layer 'towns'; its layers: cities");
  bad = o;
  bad.where = "nosuchfield = 3";
  std::string e = error_of(path, bad);
  EXPECT_NE(e.find("layer 'cities': bad -where: nosuchfield = 3 (GDAL: "), std::string::npos) << e;
  bad = o;
  bad.sql = "SELEC nonsense";
  e = error_of(path, bad);
  EXPECT_NE(e.find("-sql failed: SELEC nonsense (GDAL: "), std::string::npos) << e;
  bad = o;
  bad.source_srs = "EPSG:999999";
  EXPECT_NE(error_of(path, bad).find("-s_srs: cannot read 'EPSG:999999'"), std::string::npos);
  EXPECT_THROW(parse_edge_shape("straight"), ReadError);
  EXPECT_EQ(parse_wrap_mode("none"), WrapMode::none);
  EXPECT_EQ(parse_distance_rule("cell"), DistanceRule::cell);
}

TEST(OgrSiteReaderBadInput, BadFeaturesAreSkippedWithTheirFidAndCounted) {
  auto nan_line = std::make_shared<OGRLineString>();
  nan_line->addPoint(0, 0);
  nan_line->addPoint(std::nan(""), 1);
  const std::string path = make_dataset(temp_path("bad.gpkg"), "GPKG", "bad", "EPSG:4326",
                                        {{"POINT (1 2)", "good"},
                                         {"", "no geometry"},
                                         {"POINT EMPTY", "empty"},
                                         {"", "nan", nan_line},
                                         {"POINT (10 95)", "beyond the pole"},
                                         {"TIN (((0 0 0,0 1 0,1 0 0,0 0 0)))", "tin"},
                                         {"POINT (3 4)", "good too"}});
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(4, &messages));
  EXPECT_EQ(set.geometry.site_count, 2);
  EXPECT_EQ(set.summary.features, 7u);
  EXPECT_EQ(set.summary.skipped, 5u);
  EXPECT_EQ(set.summary.skipped_empty, 2u);
  EXPECT_EQ(set.summary.skipped_coordinate, 2u);
  EXPECT_EQ(set.summary.skipped_type, 1u);
  const std::string at = "'" + path + "', layer 'bad', FID ";
  EXPECT_TRUE(any_contains(messages, at + "2: empty geometry; feature skipped"));
  EXPECT_TRUE(any_contains(messages, at + "3: empty geometry; feature skipped"));
  EXPECT_TRUE(any_contains(messages, at + "4: NaN or infinite coordinate (nan, 1); feature skipped"));
  EXPECT_TRUE(any_contains(messages, at + "5: latitude beyond +-90 at (10, 95)"));
  EXPECT_TRUE(any_contains(messages, at + "6: unsupported geometry type 3D TIN"));
  EXPECT_TRUE(any_contains(messages, "7 features, 2 sites"));
  EXPECT_TRUE(any_contains(messages, "5 features skipped (2 empty, 1 unsupported type, 2 bad coordinate, 0 failed transformation, 0 unreadable)"));
  EXPECT_EQ(set.table.sites[1].fid, 7);

  // -strict: the first bad feature is an error.
  ReadOptions strict = options_at(4, nullptr);
  strict.strict = true;
  EXPECT_EQ(error_of(path, strict), at + "2: empty geometry (-strict)");
}

TEST(OgrSiteReaderBadInput, HugeProjectedCoordinatesAreRejectedBeforeProj) {
  // GDAL 3.6 hangs on EPSG:3857 coordinates near +-1e20: they must never reach the transformation.
  const std::string path = make_dataset(temp_path("huge.gpkg"), "GPKG", "huge", "EPSG:3857",
                                        {{"POINT (1e20 -1e20)", "huge"}, {"POINT (1000 2000)", "fine"},
                                         {"POINT (1e300 0)", "huger"}});
  std::vector<std::string> messages;
  const auto start = std::chrono::steady_clock::now();
  const SiteSet set = read_sites(path, options_at(4, &messages));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  EXPECT_EQ(set.geometry.site_count, 1);
  EXPECT_EQ(set.table.sites[0].fid, 2);
  EXPECT_TRUE(any_contains(messages, "FID 1: coordinate (1e+20, -1e+20) beyond +-1e8 metres of its CRS; feature skipped"));
  EXPECT_EQ(set.summary.skipped_coordinate, 2u);
}

TEST(OgrSiteReaderBadInput, FailedTransformationIsSkipped) {
  // A transverse Mercator coordinate far outside the projection's domain (within the 1e8 m range
  // check): PROJ cannot invert it.
  const std::string path = make_dataset(temp_path("utm.gpkg"), "GPKG", "utm", "EPSG:32631",
                                        {{"POINT (500000 4649776)", "ok"}, {"POINT (9e7 9e7)", "far"}});
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(4, &messages));
  EXPECT_EQ(set.geometry.site_count, 1);
  EXPECT_EQ(set.summary.skipped, 1u);
  EXPECT_EQ(set.summary.skipped_transform, 1u);
  EXPECT_EQ(set.summary.skipped_coordinate, 0u);
  EXPECT_TRUE(any_contains(messages, "FID 2: ")) << (messages.empty() ? "" : messages[0]);
  EXPECT_TRUE(any_contains(messages, "1 failed transformation"));
}

TEST(OgrSiteReaderBadInput, CorruptGeometryBlobSkipsOnlyThatFeature) {
  const std::string path = make_dataset(temp_path("corrupt.gpkg"), "GPKG", "corrupt", "EPSG:4326",
                                        {{"POINT (1 1)", "a"}, {"POINT (2 2)", "b"}, {"POINT (3 3)", "c"}});
  corrupt_geometry(path, 2);
  std::vector<std::string> messages;
  const SiteSet set = read_sites(path, options_at(4, &messages));
  EXPECT_EQ(set.geometry.site_count, 2);
  EXPECT_EQ(set.summary.skipped, 1u);
  EXPECT_EQ(set.summary.skipped_unreadable, 1u);
  EXPECT_EQ(set.summary.skipped_empty, 0u);
  EXPECT_TRUE(any_contains(messages, "FID 2: unreadable feature (GDAL: "));
  ReadOptions strict = options_at(4, nullptr);
  strict.strict = true;
  EXPECT_NE(error_of(path, strict).find("FID 2: unreadable feature"), std::string::npos);
}

TEST(OgrSiteReaderBadInput, NoUsableSiteIsAnError) {
  const std::string path =
      make_dataset(temp_path("none.gpkg"), "GPKG", "none", "EPSG:4326", {{"", "a"}, {"POINT (1 100)", "b"}});
  EXPECT_EQ(error_of(path, options_at(4, nullptr)),
            "'" + path + "', layer 'none': no usable site (2 features read, 2 skipped)");
  ReadOptions o = options_at(4, nullptr);
  o.where = "name = 'nobody'";
  EXPECT_EQ(error_of(path, o), "'" + path + "', layer 'none': no usable site (0 features read, 0 skipped)");
}

TEST(OgrSiteReader, SeveralLayersAreCompositeSitesEachInItsOwnCrs) {
  // Layer "merc" in Web Mercator (two points), then a layer "lonlat" added in EPSG:4326 (a line).
  const double R = 6378137.0;
  const std::string path = make_dataset(temp_path("composite.gpkg"), "GPKG", "merc", "EPSG:3857",
                                        {{"POINT (0 0)", "a"}, {"POINT (" + std::to_string(R * M_PI / 2) + " 0)", "b"}});
  {
    GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds);
    OGRSpatialReference wgs84;
    wgs84.SetWellKnownGeogCS("WGS84");
    OGRLayer* layer = ds->CreateLayer("lonlat", &wgs84, wkbLineString, nullptr);
    OGRFieldDefn kind("kind", OFTInteger);
    layer->CreateField(&kind);
    OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    f->SetField("kind", 7);
    OGRGeometry* line = nullptr;
    OGRGeometryFactory::createFromWkt("LINESTRING (10 40, 20 40)", nullptr, &line);
    f->SetGeometryDirectly(line);
    ASSERT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE);
  }
  std::vector<std::string> messages;
  ReadOptions o = options_at(9, &messages);
  o.layers = {"merc", "lonlat"};
  std::vector<double> progress;
  o.progress = [&](double f, const char*) {
    progress.push_back(f);
    return true;
  };
  const SiteSet set = read_sites(path, o);
  // One progress for the read of all layers: it never goes back, and ends at 1.
  ASSERT_FALSE(progress.empty());
  EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
  EXPECT_EQ(progress.back(), 1.0);
  o.progress = {};
  ASSERT_EQ(set.geometry.site_count, 3);
  ASSERT_EQ(set.table.source_count(), 2u);
  EXPECT_EQ(set.table.layer(0), "merc");
  EXPECT_EQ(set.table.layer(1), "lonlat");
  EXPECT_EQ(set.table.definition(1)->GetFieldIndex("kind"), 0);
  const std::vector<std::uint32_t> layers{set.table.sites[0].layer, set.table.sites[1].layer, set.table.sites[2].layer};
  EXPECT_EQ(layers, (std::vector<std::uint32_t>{0, 0, 1}));
  EXPECT_EQ(set.table.sites[2].fid, 1);  // the FID in its own layer
  EXPECT_EQ(set.table.sites[2].kind, static_cast<unsigned>(kLineSite));
  const auto cells = test::site_cells_by_site(set.geometry);
  EXPECT_EQ(*cells[1].begin(), grid::lonlat_to_code(90, 0, 9));  // transformed from its layer's CRS
  EXPECT_TRUE(cells[2].count(grid::lonlat_to_code(15, 40, 9)));  // the line, read as lon/lat
  bool named_both = false;
  for (const std::string& m : messages) named_both |= m.find("layers 'merc', 'lonlat'") != std::string::npos;
  EXPECT_TRUE(named_both);
  // A layer without a usable site is named, as when it is read alone.
  o.where = "name = 'zz'";
  EXPECT_NE(error_of(path, o).find("layer 'merc': no usable site"), std::string::npos) << error_of(path, o);
}

}  // namespace
}  // namespace qtmv::sites
