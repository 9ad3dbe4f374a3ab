// The vector writer, end to end: labels from the labeller, written with GDAL, read back with
// GDAL and checked with GEOS and GeographicLib computed here, cell by cell.
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/PolygonArea.hpp>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "../test_temp_dir.hpp"
#include "geodesic_reference.hpp"
#include "sqlite_rows.hpp"
#include "grid/qtm.hpp"
#include "label/synthetic_sites.hpp"
#include "label/label_cuda.hpp"
#include "label/labeller.hpp"
#include "write/gpkg_rows.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::write {
namespace {

using grid::Code;
using grid::LonLat;

using test::kEllipsoidArea;

std::int64_t fid_of(std::int32_t site) { return 100 + 7 * static_cast<std::int64_t>(site); }

/// Labels of a level and a site table whose source has fields name, pop, a long-named one and
/// `cells` (which collides with ours).
struct Scene {
  int level = 0;
  std::int32_t sites = 0;
  label::LabelResult result;
  sites::SiteTable table;

  CellLabels labels(bool with_distance = true, bool with_boundary = true) const {
    return {level, result.site.data(), with_distance ? result.distance_m.data() : nullptr,
            with_boundary ? result.boundary.data() : nullptr};
  }
};

/// Random points plus one near each pole and two beside +-180; the last site repeats site 2's
/// point, so it loses every tie and gets no cell.
Scene make_scene(int level, int random_points, unsigned seed) {
  Scene scene;
  scene.level = level;
  label::SiteGeometry g;
  g.level = level;
  std::vector<std::pair<double, double>> points{{10, 88.5}, {-120, -89}, {179.9, 10}, {-179.9, -20}};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-1, 1);
  for (int k = 0; k < random_points; ++k) points.push_back({lon(rng), std::asin(z(rng)) / grid::kDegree});
  points.push_back(points[2]);
  for (std::size_t s = 0; s < points.size(); ++s) label::add_point(g, points[s].first, points[s].second, static_cast<int>(s));
  scene.sites = static_cast<std::int32_t>(points.size());
  label::LabelOptions options;
  options.device = "cpu";
  scene.result = label::label_all(g.input(), options);

  auto* definition = new OGRFeatureDefn("source");
  OGRFieldDefn name("name", OFTString), pop("pop", OFTInteger64), cells("cells", OFTInteger),
      long_name("population_total", OFTReal);
  definition->AddFieldDefn(&name);
  definition->AddFieldDefn(&pop);
  definition->AddFieldDefn(&cells);
  definition->AddFieldDefn(&long_name);
  scene.table.set_source(definition, "memory", "source");
  for (std::int32_t s = 0; s < scene.sites; ++s) {
    sites::SiteRecord record;
    record.fid = fid_of(s);
    record.attributes.reset(OGRFeature::CreateFeature(definition));
    record.attributes->SetField("name", ("site " + std::to_string(s)).c_str());
    record.attributes->SetField("pop", static_cast<GIntBig>(1000 + s));
    record.attributes->SetField("cells", -s);
    record.attributes->SetField("population_total", 0.5 * s);
    record.kind = sites::kPointSite;
    scene.table.sites.push_back(std::move(record));
  }
  return scene;
}

/// A path under the test directory, removed (with whatever GDAL made there) on destruction.
struct TempPath {
  // In the process's own directory: two test runs at once (two checkouts) must not share files.
  explicit TempPath(const std::string& name) : path(qtmv::test::process_temp_dir() + "/vector_" + name) {
    std::filesystem::remove_all(path);
  }
  ~TempPath() { std::filesystem::remove_all(path); }
  std::string path;
};

GDALDatasetUniquePtr open_vector(const std::string& path) {
  return GDALDatasetUniquePtr(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
}

using test::cell_area;

class VectorTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { GDALAllRegister(); }
};

/// Site pairs (site ids, a < b) that share a cell edge, by a direct scan of the neighbours.
std::set<std::pair<std::int32_t, std::int32_t>> neighbour_pairs(const Scene& scene) {
  std::set<std::pair<std::int32_t, std::int32_t>> pairs;
  for (Code code = 0; code < grid::cell_count(scene.level); ++code) {
    Code nb[3];
    grid::neighbours(code, scene.level, nb);
    for (Code n : nb) {
      const std::int32_t a = scene.result.site[code], b = scene.result.site[n];
      if (a != b) pairs.insert({std::min(a, b), std::max(a, b)});
    }
  }
  return pairs;
}

/// The geodesic length (metres) of the edge two neighbouring cells share: the two vertices of
/// `code`'s polygon that `other`'s polygon has too (+180 and -180 are the same meridian).
double shared_edge_length(Code code, Code other, int level) {
  LonLat a[grid::kMaxPolygonCorners], b[grid::kMaxPolygonCorners];
  const int na = grid::cell_polygon(grid::cell_of(code, level), level, a);
  const int nb = grid::cell_polygon(grid::cell_of(other, level), level, b);
  std::vector<LonLat> shared;
  for (int i = 0; i < na; ++i) {
    for (int j = 0; j < nb; ++j) {
      const bool same_lon = a[i].lon == b[j].lon || (std::fabs(a[i].lon) == 180 && std::fabs(b[j].lon) == 180);
      if (a[i].lat == b[j].lat && same_lon) {
        shared.push_back(a[i]);
        break;
      }
    }
  }
  EXPECT_EQ(shared.size(), 2u) << "cells " << code << " and " << other;
  if (shared.size() != 2) return 0;
  double s12 = 0;
  GeographicLib::Geodesic::WGS84().Inverse(shared[0].lat, shared[0].lon, shared[1].lat, shared[1].lon, s12);
  return s12;
}

TEST_F(VectorTest, RegionsTileTheGlobe) {
  for (int level : {3, 5}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const Scene scene = make_scene(level, 20, 7 + level);
    const std::int32_t empty_site = scene.sites - 1;
    const TempPath out("regions_" + std::to_string(level) + ".gpkg");
    VectorOptions options;
    options.layers = {"regions"};
    write_vector(out.path, scene.labels(), scene.table, options);

    // Expected per site: cells, and the area of its cells with geodesic edges.
    std::vector<std::uint64_t> cells(scene.sites, 0);
    std::vector<double> area(scene.sites, 0.0);
    for (Code code = 0; code < grid::cell_count(level); ++code) {
      ++cells[scene.result.site[code]];
      area[scene.result.site[code]] += cell_area(code, level);
    }
    ASSERT_EQ(cells[empty_site], 0u) << "the scene should have a site without cells";
    const std::int32_t north_site = scene.result.site[0];  // holds the north pole's cell of octant 0
    ASSERT_EQ(north_site, 0);

    auto ds = open_vector(out.path);
    ASSERT_TRUE(ds);
    OGRLayer* layer = ds->GetLayerByName("regions");
    ASSERT_NE(layer, nullptr);
    EXPECT_EQ(ds->GetLayerByName("boundary_cells"), nullptr);
    ASSERT_EQ(layer->GetFeatureCount(), scene.sites);
    const OGRFeatureDefn* defn = layer->GetLayerDefn();
    for (const char* name : {"name", "pop", "cells", "population_total", "site_fid", "qtmv_cells", "area_m2"}) {
      EXPECT_GE(defn->GetFieldIndex(name), 0) << name;
    }
    EXPECT_EQ(defn->GetFieldDefn(defn->GetFieldIndex("site_fid"))->GetType(), OFTInteger64);
    EXPECT_EQ(defn->GetFieldDefn(defn->GetFieldIndex("area_m2"))->GetType(), OFTReal);
    const OGRSpatialReference* srs = layer->GetSpatialRef();
    ASSERT_NE(srs, nullptr);
    EXPECT_STREQ(srs->GetAuthorityCode(nullptr), "4326");

    std::vector<std::unique_ptr<OGRGeometry>> shapes;
    double total_area = 0;
    std::uint64_t total_cells = 0;
    std::int32_t s = 0;
    for (auto& feature : *layer) {
      SCOPED_TRACE("site " + std::to_string(s));
      EXPECT_EQ(feature->GetFieldAsInteger64("site_fid"), fid_of(s));
      EXPECT_EQ(std::string(feature->GetFieldAsString("name")), "site " + std::to_string(s));
      EXPECT_EQ(feature->GetFieldAsInteger64("pop"), 1000 + s);
      EXPECT_EQ(feature->GetFieldAsInteger("cells"), -s);  // the source's, kept
      EXPECT_DOUBLE_EQ(feature->GetFieldAsDouble("population_total"), 0.5 * s);
      const auto got_cells = static_cast<std::uint64_t>(feature->GetFieldAsInteger64("qtmv_cells"));
      EXPECT_EQ(got_cells, cells[s]);
      total_cells += got_cells;
      const double got_area = feature->GetFieldAsDouble("area_m2");
      EXPECT_NEAR(got_area, area[s], 1e-9 * kEllipsoidArea);
      total_area += got_area;
      const OGRGeometry* geometry = feature->GetGeometryRef();
      if (s == empty_site) {
        EXPECT_TRUE(geometry == nullptr || geometry->IsEmpty());
        EXPECT_EQ(got_area, 0.0);
        shapes.emplace_back(nullptr);
      } else {
        ASSERT_NE(geometry, nullptr);
        EXPECT_EQ(wkbFlatten(geometry->getGeometryType()), wkbMultiPolygon);
        EXPECT_TRUE(geometry->IsValid()) << geometry->exportToWkt();
        OGREnvelope box;
        geometry->getEnvelope(&box);
        EXPECT_GE(box.MinX, -180.0);
        EXPECT_LE(box.MaxX, 180.0);
        EXPECT_GE(box.MinY, -90.0);
        EXPECT_LE(box.MaxY, 90.0);
        shapes.emplace_back(geometry->clone());
      }
      ++s;
    }
    EXPECT_EQ(s, scene.sites);
    EXPECT_EQ(total_cells, grid::cell_count(level));
    EXPECT_NEAR(total_area, kEllipsoidArea, 1e-4 * kEllipsoidArea);
    // The regions around the poles: runs along latitude +-90, cut at +-180, and their own
    // small caps, not the rest of the Earth.
    const std::int32_t south_site = scene.result.site[4 * grid::cells_per_octant(level)];  // octant 4's pole cell
    ASSERT_EQ(south_site, 1);
    for (std::int32_t polar : {north_site, south_site}) {
      EXPECT_LT(area[polar], 0.2 * kEllipsoidArea);
      OGREnvelope box;
      shapes[polar]->getEnvelope(&box);
      EXPECT_TRUE(box.MaxY == 90.0 || box.MinY == -90.0) << "site " << polar;
    }

    // No two regions overlap: neighbouring pairs and a random sample of others.
    std::vector<std::pair<std::int32_t, std::int32_t>> sample;
    for (const auto& pair : neighbour_pairs(scene)) sample.push_back(pair);
    std::mt19937 rng(level);
    std::uniform_int_distribution<std::int32_t> pick(0, empty_site - 1);
    for (int k = 0; k < 20; ++k) sample.push_back({pick(rng), pick(rng)});
    for (const auto& [a, b] : sample) {
      if (a == b) continue;
      std::unique_ptr<OGRGeometry> common(shapes[a]->Intersection(shapes[b].get()));
      ASSERT_NE(common, nullptr) << a << " " << b;
      double common_area = 0;
      if (OGR_GT_IsSurface(wkbFlatten(common->getGeometryType())) ||
          wkbFlatten(common->getGeometryType()) == wkbMultiPolygon ||
          wkbFlatten(common->getGeometryType()) == wkbGeometryCollection) {
        common_area = OGR_G_Area(OGRGeometry::ToHandle(common.get()));
      }
      EXPECT_LT(common_area, 1e-9) << "sites " << a << " and " << b << " overlap";
    }
  }
}

/// Writes the regions of `labels` (site ids 0 .. sites - 1, FIDs fid_of) and checks each area
/// against its cells' and each geometry's validity; returns the regions read back.
std::vector<std::unique_ptr<OGRGeometry>> check_region_areas(int level, const std::vector<std::int32_t>& labels,
                                                             std::int32_t sites, const std::string& name) {
  sites::SiteTable table;
  for (std::int32_t s = 0; s < sites; ++s) {
    table.sites.emplace_back();
    table.sites.back().fid = fid_of(s);
  }
  std::vector<double> area(sites, 0.0);
  for (Code code = 0; code < grid::cell_count(level); ++code) area[labels[code]] += cell_area(code, level);
  const TempPath out(name);
  VectorOptions options;
  options.layers = {"regions"};
  write_vector(out.path, {level, labels.data(), nullptr, nullptr}, table, options);
  auto ds = open_vector(out.path);
  std::vector<std::unique_ptr<OGRGeometry>> shapes;
  EXPECT_TRUE(ds);
  if (!ds) return shapes;
  std::int32_t s = 0;
  double total = 0;
  for (auto& feature : *ds->GetLayerByName("regions")) {
    EXPECT_NEAR(feature->GetFieldAsDouble("area_m2"), area[s], 1e-9 * kEllipsoidArea) << "site " << s;
    total += feature->GetFieldAsDouble("area_m2");
    EXPECT_TRUE(feature->GetGeometryRef()->IsValid()) << "site " << s;
    shapes.emplace_back(feature->GetGeometryRef()->clone());
    ++s;
  }
  EXPECT_EQ(s, sites);
  EXPECT_NEAR(total, kEllipsoidArea, 1e-4 * kEllipsoidArea);
  return shapes;
}

/// Geodesic area (square metres) of a polygon read back: its rings' vertices joined by geodesics,
/// the shell counter-clockwise, the holes clockwise.
double geodesic_polygon_area(const OGRPolygon& polygon) {
  double area = 0;
  for (int r = 0; r < polygon.getNumInteriorRings() + 1; ++r) {
    const OGRLinearRing* ring = r == 0 ? polygon.getExteriorRing() : polygon.getInteriorRing(r - 1);
    GeographicLib::PolygonArea measure(GeographicLib::Geodesic::WGS84());
    for (int k = 0; k + 1 < ring->getNumPoints(); ++k) measure.AddPoint(ring->getY(k), ring->getX(k));  // closed: last = first
    double perimeter = 0, ring_area = 0;
    measure.Compute(/*reverse=*/r > 0, /*sign=*/false, perimeter, ring_area);
    area += r == 0 ? ring_area : -ring_area;
  }
  return area;
}

TEST_F(VectorTest, AllRingVerticesMakeTheGeodesicAreaTheRegionsArea) {
  // A cap north of 70N, a band along the equator and the rest by octant: long runs along parallels.
  const int level = 5;
  std::vector<std::int32_t> labels(grid::cell_count(level));
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    const LonLat c = grid::cell_centre(code, level);
    labels[code] = c.lat > 70 ? 0 : std::fabs(c.lat) < 15 ? 1 : 2 + grid::cell_of(code, level).octant;
  }
  const std::int32_t sites = 10;
  sites::SiteTable table;
  for (std::int32_t s = 0; s < sites; ++s) table.sites.emplace_back().fid = fid_of(s);
  // Geodesic area of each region read back, against area_m2; the largest gap (square metres).
  const auto worst_gap = [&](bool all_vertices, const std::string& name, std::size_t* points) {
    const TempPath out(name);
    VectorOptions options;
    options.layers = {"regions"};
    options.ring_vertices = all_vertices ? VectorOptions::Vertices::all : VectorOptions::Vertices::corners;
    write_vector(out.path, {level, labels.data(), nullptr, nullptr}, table, options);
    auto ds = open_vector(out.path);
    EXPECT_TRUE(ds);
    double worst = 0;
    *points = 0;
    if (!ds) return worst;
    for (auto& feature : *ds->GetLayerByName("regions")) {
      const auto* multi = feature->GetGeometryRef()->toMultiPolygon();
      double area = 0;
      for (const OGRPolygon* part : *multi) {
        area += geodesic_polygon_area(*part);
        for (const OGRLinearRing* ring : *part) *points += static_cast<std::size_t>(ring->getNumPoints());
      }
      worst = std::max(worst, std::fabs(area - feature->GetFieldAsDouble("area_m2")));
      EXPECT_TRUE(multi->IsValid()) << "site FID " << feature->GetFieldAsInteger64("site_fid");
    }
    return worst;
  };
  std::size_t all_points = 0, corner_points = 0;
  EXPECT_LT(worst_gap(true, "all_vertices.gpkg", &all_points), 1e-9 * kEllipsoidArea);
  // With the corners only, the long runs read as geodesics cut poleward: the areas differ.
  EXPECT_GT(worst_gap(false, "corners.gpkg", &corner_points), 1e-3 * kEllipsoidArea);
  EXPECT_GT(all_points, corner_points);
}

TEST_F(VectorTest, RegionsWithHolesAndLargePolarRegions) {
  // Site 1 a ring around (10, 10), site 0 outside it and again inside: polygons with holes.
  {
    const int level = 5;
    const grid::Vec3 centre = grid::unit_vector(10, 10);
    std::vector<std::int32_t> labels(grid::cell_count(level));
    for (Code code = 0; code < labels.size(); ++code) {
      const double d = grid::chord2(grid::cell_centre_vector(code, level), centre);
      labels[code] = (d < 0.02 || d > 0.1) ? 0 : 1;
    }
    const auto shapes = check_region_areas(level, labels, 2, "holes.gpkg");
    ASSERT_EQ(shapes.size(), 2u);
    const OGRMultiPolygon* ring_site = shapes[1]->toMultiPolygon();
    ASSERT_EQ(ring_site->getNumGeometries(), 1);
    EXPECT_EQ(ring_site->getGeometryRef(0)->getNumInteriorRings(), 1);
  }
  // A cap around the north pole larger than a hemisphere, and a small southern region: each
  // gets its own area, not the other's.
  {
    const int level = 4;
    label::SiteGeometry g;
    g.level = level;
    label::add_point(g, 0, 89.9, 0);
    label::add_point(g, 30, -70, 1);
    label::LabelOptions lo;
    lo.device = "cpu";
    const label::LabelResult result = label::label_all(g.input(), lo);
    check_region_areas(level, result.site, 2, "large_polar.gpkg");
  }
}

/// One site, at (5, 5), FID 1: every cell of the level is its.
struct OneSite {
  explicit OneSite(int level_) : level(level_) {
    label::SiteGeometry g;
    g.level = level;
    label::add_point(g, 5, 5, 0);
    label::LabelOptions lo;
    lo.device = "cpu";
    result = label::label_all(g.input(), lo);
    table.sites.emplace_back();
    table.sites[0].fid = 1;
  }
  CellLabels labels() const { return {level, result.site.data(), nullptr, nullptr}; }
  int level;
  label::LabelResult result;
  sites::SiteTable table;
};

TEST_F(VectorTest, OneSiteIsTheWholeEllipsoid) {
  const OneSite one(3);
  const int level = one.level;
  const TempPath out("one_site.gpkg");
  write_vector(out.path, one.labels(), one.table, VectorOptions{});
  auto ds = open_vector(out.path);
  ASSERT_TRUE(ds);
  OGRLayer* regions = ds->GetLayerByName("regions");
  ASSERT_NE(regions, nullptr);
  ASSERT_EQ(regions->GetFeatureCount(), 1);
  auto feature = std::unique_ptr<OGRFeature, decltype(&OGRFeature::DestroyFeature)>(regions->GetNextFeature(),
                                                                                      &OGRFeature::DestroyFeature);
  EXPECT_NEAR(feature->GetFieldAsDouble("area_m2"), kEllipsoidArea, 1e-9 * kEllipsoidArea);
  EXPECT_EQ(feature->GetFieldAsInteger64("cells"), static_cast<GIntBig>(grid::cell_count(level)));
  EXPECT_TRUE(feature->GetGeometryRef()->IsValid());
  EXPECT_EQ(ds->GetLayerByName("boundary_cells")->GetFeatureCount(), 0);
  EXPECT_EQ(ds->GetLayerByName("voronoi_edges")->GetFeatureCount(), 0);
}

TEST_F(VectorTest, BoundaryCells) {
  const Scene scene = make_scene(4, 15, 3);
  const TempPath out("boundary.gpkg");
  VectorOptions options;
  options.layers = {"boundary_cells"};
  for (bool flags : {true, false}) {  // given, and computed by the writer
    SCOPED_TRACE(flags ? "flags given" : "flags computed");
    write_vector(out.path, scene.labels(true, flags), scene.table, options);
    std::uint64_t flagged = 0;
    for (std::uint8_t b : scene.result.boundary) flagged += b;
    ASSERT_GT(flagged, 0u);
    auto ds = open_vector(out.path);
    ASSERT_TRUE(ds);
    OGRLayer* layer = ds->GetLayerByName("boundary_cells");
    ASSERT_NE(layer, nullptr);
    EXPECT_EQ(static_cast<std::uint64_t>(layer->GetFeatureCount()), flagged);
    std::set<Code> seen;
    for (auto& feature : *layer) {
      const auto code = static_cast<Code>(feature->GetFieldAsInteger64("code"));
      ASSERT_LT(code, grid::cell_count(scene.level));
      EXPECT_TRUE(seen.insert(code).second);
      EXPECT_EQ(scene.result.boundary[code], 1);
      EXPECT_EQ(feature->GetFieldAsInteger64("site_fid"), fid_of(scene.result.site[code]));
      const OGRGeometry* geometry = feature->GetGeometryRef();
      ASSERT_NE(geometry, nullptr);
      EXPECT_EQ(wkbFlatten(geometry->getGeometryType()), wkbPolygon);
      const LonLat c = grid::cell_centre(code, scene.level);
      OGRPoint centre(c.lon, c.lat);
      EXPECT_TRUE(geometry->Contains(&centre)) << "cell " << code;
    }
  }
}

TEST_F(VectorTest, VoronoiEdgesArePairsOfNeighbours) {
  for (int level : {3, 6}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const Scene scene = make_scene(level, 30, 21);
    const TempPath out("edges_" + std::to_string(level) + ".gpkg");
    VectorOptions options;
    options.layers = {"voronoi_edges"};
    write_vector(out.path, scene.labels(), scene.table, options);

    // Expected: the pairs of a direct scan, and each pair's edge length summed from both sides.
    const auto pairs = neighbour_pairs(scene);
    std::map<std::pair<std::int64_t, std::int64_t>, double> expected;
    for (Code code = 0; code < grid::cell_count(level); ++code) {
      Code nb[3];
      grid::neighbours(code, level, nb);
      for (Code n : nb) {
        const std::int32_t a = scene.result.site[code], b = scene.result.site[n];
        if (a != b) expected[{fid_of(std::min(a, b)), fid_of(std::max(a, b))}] += 0.5 * shared_edge_length(code, n, level);
      }
    }
    ASSERT_EQ(expected.size(), pairs.size());

    auto ds = open_vector(out.path);
    ASSERT_TRUE(ds);
    OGRLayer* layer = ds->GetLayerByName("voronoi_edges");
    ASSERT_NE(layer, nullptr);
    std::map<std::pair<std::int64_t, std::int64_t>, double> got;
    for (auto& feature : *layer) {
      const std::pair<std::int64_t, std::int64_t> key{feature->GetFieldAsInteger64("site_a"),
                                                      feature->GetFieldAsInteger64("site_b")};
      EXPECT_LT(key.first, key.second);
      EXPECT_EQ(got.count(key), 0u) << "pair written twice";
      const double length = feature->GetFieldAsDouble("length_m");
      EXPECT_GT(length, 0.0);
      got[key] = length;
      const OGRGeometry* geometry = feature->GetGeometryRef();
      ASSERT_NE(geometry, nullptr);
      EXPECT_EQ(wkbFlatten(geometry->getGeometryType()), wkbMultiLineString);
      EXPECT_FALSE(geometry->IsEmpty());
    }
    ASSERT_EQ(got.size(), expected.size());
    for (const auto& [key, length] : expected) {
      ASSERT_EQ(got.count(key), 1u) << key.first << "-" << key.second << " missing";
      EXPECT_NEAR(got[key], length, 1e-9 * length + 1e-6) << key.first << "-" << key.second;
    }
  }
}

TEST_F(VectorTest, VoronoiEdgeLengthsFromTheRegionsPassAreTheSame) {
  // Written after regions, voronoi_edges takes its lengths from the regions' pass over the
  // outline cells and solves only the edges on the cut at +-180 itself; alone or before
  // regions, it solves every edge. The lengths must be the same to the bit, and the scene has
  // pairs with edges on the cut (sites beside +-180) and at the poles.
  for (int level : {3, 7}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const Scene scene = make_scene(level, 40, 5);
    std::vector<std::map<std::pair<std::int64_t, std::int64_t>, double>> lengths;
    std::size_t pairs_on_the_cut = 0;
    for (const std::vector<std::string>& layers : std::vector<std::vector<std::string>>{
             {"regions", "voronoi_edges"}, {"voronoi_edges"}, {"voronoi_edges", "regions"}}) {
      const TempPath out("edge_lengths_" + std::to_string(level) + "_" + std::to_string(lengths.size()) + ".gpkg");
      VectorOptions options;
      options.layers = layers;
      write_vector(out.path, scene.labels(), scene.table, options);
      auto ds = open_vector(out.path);
      ASSERT_TRUE(ds);
      OGRLayer* layer = ds->GetLayerByName("voronoi_edges");
      ASSERT_NE(layer, nullptr);
      auto& got = lengths.emplace_back();
      for (auto& feature : *layer) {
        got[{feature->GetFieldAsInteger64("site_a"), feature->GetFieldAsInteger64("site_b")}] =
            feature->GetFieldAsDouble("length_m");
        if (lengths.size() > 1) continue;
        const auto* lines = feature->GetGeometryRef()->toMultiLineString();
        bool on_cut = false;
        for (const OGRLineString* line : *lines) {
          for (int k = 1; k < line->getNumPoints(); ++k) {
            on_cut = on_cut || (std::fabs(line->getX(k - 1)) == 180.0 && std::fabs(line->getX(k)) == 180.0);
          }
        }
        pairs_on_the_cut += on_cut;
      }
    }
    EXPECT_GT(pairs_on_the_cut, 0u);
    ASSERT_FALSE(lengths[0].empty());
    EXPECT_EQ(lengths[0], lengths[1]);
    EXPECT_EQ(lengths[0], lengths[2]);
  }
}

TEST_F(VectorTest, CellsLayerOnlyWhenAsked) {
  // Level 7 has 131 072 cells: more than one transaction.
  const Scene scene = make_scene(7, 10, 5);
  const TempPath plain("cells_default.gpkg"), asked("cells_asked.gpkg"), no_distance("cells_nodist.gpkg");
  VectorOptions options;
  options.layers = {"regions"};
  write_vector(plain.path, scene.labels(), scene.table, options);
  {
    auto ds = open_vector(plain.path);
    ASSERT_TRUE(ds);
    EXPECT_EQ(ds->GetLayerByName("cells"), nullptr);
  }
  options.layers = {"cells"};
  write_vector(asked.path, scene.labels(), scene.table, options);
  write_vector(no_distance.path, scene.labels(false, false), scene.table, options);
  for (const std::string& path : {asked.path, no_distance.path}) {
    const bool with_distance = path == asked.path;
    SCOPED_TRACE(path);
    auto ds = open_vector(path);
    ASSERT_TRUE(ds);
    ASSERT_EQ(ds->GetLayerCount(), 1);
    OGRLayer* layer = ds->GetLayerByName("cells");
    ASSERT_NE(layer, nullptr);
    ASSERT_EQ(static_cast<std::uint64_t>(layer->GetFeatureCount()), grid::cell_count(scene.level));
    Code expected_code = 0;
    int mismatches = 0;
    for (auto& feature : *layer) {
      const auto code = static_cast<Code>(feature->GetFieldAsInteger64("code"));
      mismatches += code != expected_code++;
      mismatches += feature->GetFieldAsInteger64("site_fid") != fid_of(scene.result.site[code]);
      mismatches += feature->GetFieldAsInteger("boundary") != scene.result.boundary[code];
      if (with_distance) {
        mismatches += feature->GetFieldAsDouble("distance_m") != static_cast<double>(scene.result.distance_m[code]);
      } else {
        mismatches += !feature->IsFieldNull(feature->GetFieldIndex("distance_m"));
      }
    }
    EXPECT_EQ(mismatches, 0);
  }
}

TEST_F(VectorTest, GeoPackageCellLayersHaveNoSpatialIndexUnlessAsked) {
  const Scene scene = make_scene(5, 10, 7);
  const TempPath plain("spi_default.gpkg"), asked("spi_asked.gpkg");
  VectorOptions options;
  options.layers = {"regions", "boundary_cells", "voronoi_edges", "cells"};
  write_vector(plain.path, scene.labels(), scene.table, options);
  options.layer_options = {"SPATIAL_INDEX=YES"};
  write_vector(asked.path, scene.labels(), scene.table, options);
  const auto has_rtree = [](GDALDataset& ds, const char* layer) {
    OGRLayer* result = ds.ExecuteSQL(
        (std::string("SELECT COUNT(*) FROM sqlite_master WHERE name = 'rtree_") + layer + "_geom'").c_str(), nullptr,
        nullptr);
    EXPECT_NE(result, nullptr);
    if (!result) return false;
    OGRFeature* row = result->GetNextFeature();
    const bool found = row && row->GetFieldAsInteger(0) > 0;
    OGRFeature::DestroyFeature(row);
    ds.ReleaseResultSet(result);
    return found;
  };
  {
    auto ds = open_vector(plain.path);
    ASSERT_TRUE(ds);
    EXPECT_TRUE(has_rtree(*ds, "regions"));
    EXPECT_TRUE(has_rtree(*ds, "voronoi_edges"));
    EXPECT_FALSE(has_rtree(*ds, "boundary_cells"));
    EXPECT_FALSE(has_rtree(*ds, "cells"));
  }
  {
    auto ds = open_vector(asked.path);
    ASSERT_TRUE(ds);
    for (const char* layer : {"regions", "boundary_cells", "voronoi_edges", "cells"}) {
      EXPECT_TRUE(has_rtree(*ds, layer)) << layer;
    }
  }
}

/// Everything a GeoPackage holds that the writer makes, as text: the metadata tables, the schema
/// (by name: a trigger dropped and made again comes later in sqlite_master) and every row of
/// every table, blobs in hex and reals to 17 digits.
std::vector<std::string> gpkg_dump(const std::string& path) {
  std::vector<std::string> out;
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << path;
  const auto query = [&](const std::string& sql) {
    const std::vector<std::string> rows = test::sqlite_rows(db, sql, sql.substr(0, 40) + ":");
    out.insert(out.end(), rows.begin(), rows.end());
  };
  query("SELECT * FROM gpkg_contents ORDER BY table_name");
  query("SELECT * FROM gpkg_ogr_contents ORDER BY table_name");
  query("SELECT * FROM gpkg_geometry_columns ORDER BY table_name");
  query("SELECT * FROM sqlite_sequence ORDER BY name");
  query("SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY name");
  const auto exists = [&](const std::string& table) {
    sqlite3_stmt* st = nullptr;
    sqlite3_prepare_v2(db, ("SELECT 1 FROM sqlite_master WHERE name = '" + table + "'").c_str(), -1, &st, nullptr);
    const bool found = sqlite3_step(st) == SQLITE_ROW;
    sqlite3_finalize(st);
    return found;
  };
  for (const char* table : {"regions", "boundary_cells", "voronoi_edges", "cells"}) {
    if (!exists(table)) continue;
    query(std::string("SELECT * FROM \"") + table + "\" ORDER BY fid");
    // The spatial index: its boxes (float32, as SQLite rounds them) and its check. The nodes are
    // not compared: the direct rows' tree is packed, GDAL's grown one row at a time.
    const std::string rtree = std::string("rtree_") + table + "_geom";
    if (!exists(rtree)) continue;
    query("SELECT * FROM " + rtree + " ORDER BY id");
    query("SELECT rtreecheck('" + rtree + "')");
  }
  sqlite3_close(db);
  return out;
}

/// Writes `labels` with direct GeoPackage rows and through OGR; both files must be the same.
/// Returns the number of rows compared.
std::size_t expect_same_as_ogr(const CellLabels& labels, const sites::SiteTable& table, const VectorOptions& options) {
  const TempPath direct("direct_rows.gpkg"), ogr("ogr_rows.gpkg");
  write_vector(direct.path, labels, table, options);
  {
    CPLConfigOptionSetter through_ogr("QTMV_GPKG_DIRECT_ROWS", "NO", false);
    write_vector(ogr.path, labels, table, options);
  }
  const std::vector<std::string> expected = gpkg_dump(ogr.path), got = gpkg_dump(direct.path);
  EXPECT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < std::min(got.size(), expected.size()); ++k) {
    if (got[k] != expected[k]) {
      ADD_FAILURE() << "row " << k << ": " << got[k] << "\n expected " << expected[k];
      break;
    }
  }
  return expected.size();
}

TEST_F(VectorTest, GeoPackageDirectRowsAreWhatOgrWrites) {
  // Level 7: 131 072 cells, more than one transaction and a last INSERT of fewer rows. One site
  // without a FID (null site_fid), and labels without distances (null distance_m) for a second file.
  Scene scene = make_scene(7, 40, 11);
  scene.table.sites[3].fid = OGRNullFID;
  CPLConfigOptionSetter fixed_date("OGR_CURRENT_DATE", "2026-11-22T00:00:00.000Z", false);
  VectorOptions options;
  options.layers = {"regions", "boundary_cells", "voronoi_edges", "cells"};
  for (bool with_distance : {true, false}) {
    SCOPED_TRACE(with_distance ? "with distances" : "without distances");
    EXPECT_GT(expect_same_as_ogr(scene.labels(with_distance), scene.table, options), grid::cell_count(scene.level));
  }
  // No boundary cell at all: the table stays as GDAL leaves an empty one.
  const OneSite one(3);
  expect_same_as_ogr(one.labels(), one.table, options);
  {
    // Every layer with a spatial index: the cells' R-tree (131 072 rows, over a commit) and R-trees
    // of three levels for the regions and edges (more than 51 x 51 rows).
    SCOPED_TRACE("every layer indexed");
    Scene many = make_scene(7, 3000, 17);
    many.table.sites[3].fid = OGRNullFID;
    VectorOptions indexed = options;
    indexed.layer_options = {"SPATIAL_INDEX=YES"};
    expect_same_as_ogr(many.labels(), many.table, indexed);
  }

  // Composite sites: a second source layer with a field of its own and one of the first's, null
  // and unset values, a site without attributes, text beyond ASCII; then values that OGR mends
  // (text longer than its field's width, a Date field), which the regions write through OGR.
  Scene two = make_scene(6, 30, 5);
  auto* second = new OGRFeatureDefn("second");
  OGRFieldDefn name("name", OFTString), kind("kind", OFTString);
  second->AddFieldDefn(&name);
  second->AddFieldDefn(&kind);
  two.table.add_source(second, "memory", "second");
  for (std::size_t s = 0; s < two.table.sites.size(); s += 3) {
    sites::SiteRecord& site = two.table.sites[s];
    site.layer = 1;
    site.attributes.reset(OGRFeature::CreateFeature(second));
    if (s % 2 == 0) site.attributes->SetField("name", ("Zürich ø " + std::to_string(s)).c_str());
    if (s % 9 == 0) site.attributes->SetFieldNull(1);
    else site.attributes->SetField("kind", "city");
  }
  two.table.sites[4].attributes.reset();
  two.table.sites[5].attributes->SetFieldNull(1);
  options.layers = {"regions", "voronoi_edges"};
  expect_same_as_ogr(two.labels(), two.table, options);
  {
    SCOPED_TRACE("text longer than its width");
    Scene wide = make_scene(5, 10, 2);
    const_cast<OGRFeatureDefn*>(wide.table.definition())->GetFieldDefn(0)->SetWidth(4);
    CPLPushErrorHandler(CPLQuietErrorHandler);  // GDAL warns of the long values
    expect_same_as_ogr(wide.labels(), wide.table, options);
    CPLPopErrorHandler();
  }
  {
    // With TRUNCATE_FIELDS=YES, GDAL cuts a text longer than its field's width: such a source's
    // regions go through OGR. The check runs on all cores: one long value at a time, first, in
    // the middle and last, must each be seen.
    VectorOptions truncating = options;
    truncating.layer_options.push_back("TRUNCATE_FIELDS=YES");
    for (const int place : {0, 1, 2}) {
      Scene narrow = make_scene(6, 5000, 6);
      const std::size_t at = place * (narrow.table.sites.size() - 1) / 2;
      SCOPED_TRACE("a text longer than its width at site " + std::to_string(at));
      const_cast<OGRFeatureDefn*>(narrow.table.definition())->GetFieldDefn(0)->SetWidth(10);  // "site 5003" fits
      narrow.table.sites[at].attributes->SetField("name", "a name longer than ten characters");
      CPLPushErrorHandler(CPLQuietErrorHandler);  // GDAL warns of the value it cuts
      expect_same_as_ogr(narrow.labels(), narrow.table, truncating);
      CPLPopErrorHandler();
    }
  }
  {
    SCOPED_TRACE("a Date field");
    Scene dated = make_scene(5, 10, 3);
    const OGRFeatureDefn* plain = dated.table.definition();
    auto* with_day = new OGRFeatureDefn("dated");
    for (int f = 0; f < plain->GetFieldCount(); ++f) with_day->AddFieldDefn(plain->GetFieldDefn(f));
    OGRFieldDefn day("day", OFTDate);
    with_day->AddFieldDefn(&day);
    for (sites::SiteRecord& site : dated.table.sites) {
      sites::FeaturePtr copy(OGRFeature::CreateFeature(with_day));
      copy->SetFrom(site.attributes.get());
      copy->SetField("day", 2026, 11, 26);
      site.attributes = std::move(copy);
    }
    dated.table.set_source(with_day, "memory", "dated");
    expect_same_as_ogr(dated.labels(), dated.table, options);
  }
}

TEST_F(VectorTest, GeodesicsOnAGpuOrNotGiveTheCpusFile) {
  // The regions' areas and the Voronoi edges' lengths solved on the first GPU (on the GPU
  // machine) are the CPU's to the bit: the same rows. A device that cannot be used (here an
  // ordinal past the host's) leaves them to the CPU, with a warning naming it.
  const Scene scene = make_scene(6, 60, 9);
  CPLConfigOptionSetter fixed_date("OGR_CURRENT_DATE", "2026-11-22T00:00:00.000Z", false);
  const auto dump_with = [&](int device, std::vector<std::string>* warnings) {
    const TempPath out("geodesic_device_" + std::to_string(device) + ".gpkg");
    VectorOptions options;
    options.layers = {"regions", "voronoi_edges"};
    options.geodesic_device = device;
    options.messages = [&](qtmv::Severity severity, const std::string& message) {
      if (severity == qtmv::Severity::warning) warnings->push_back(message);
    };
    write_vector(out.path, scene.labels(), scene.table, options);
    return gpkg_dump(out.path);
  };
  std::vector<std::string> warnings;
  const std::vector<std::string> cpu = dump_with(-1, &warnings);
  EXPECT_TRUE(warnings.empty());
  const int devices = label::cuda::device_count();
  if (devices > 0) {
    EXPECT_EQ(dump_with(0, &warnings), cpu);
    EXPECT_TRUE(warnings.empty());
  }
  EXPECT_EQ(dump_with(devices, &warnings), cpu);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("on the CPU instead of cuda:" + std::to_string(devices)), std::string::npos) << warnings[0];
}

TEST_F(VectorTest, GeoPackageDirectRowsOnlyWhereTheyApply) {
  OGRSpatialReference srs;
  srs.importFromEPSG(4326);
  const TempPath gpkg("direct_open.gpkg");
  GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GPKG")->Create(gpkg.path.c_str(), 0, 0, 0,
                                                                                   GDT_Unknown, nullptr));
  ASSERT_TRUE(ds);
  const char* no_index[] = {"SPATIAL_INDEX=NO", nullptr};
  OGRLayer* plain = ds->CreateLayer("plain", &srs, wkbPolygon, const_cast<char**>(no_index));
  OGRFieldDefn code("code", OFTInteger64);
  ASSERT_EQ(plain->CreateField(&code), OGRERR_NONE);
  EXPECT_NE(GpkgRows::open(*ds, *plain, {0}), nullptr);
  {
    CPLConfigOptionSetter off("QTMV_GPKG_DIRECT_ROWS", "NO", false);
    EXPECT_EQ(GpkgRows::open(*ds, *plain, {0}), nullptr);
  }
  // A table with rows already, or with a trigger of someone else's: OGR features instead.
  OGRLayer* filled = ds->CreateLayer("filled", &srs, wkbPolygon, const_cast<char**>(no_index));
  OGRFeature feature(filled->GetLayerDefn());
  ASSERT_EQ(filled->CreateFeature(&feature), OGRERR_NONE);
  EXPECT_EQ(GpkgRows::open(*ds, *filled, {}), nullptr);
  OGRLayer* watched = ds->CreateLayer("watched", &srs, wkbPolygon, const_cast<char**>(no_index));
  ASSERT_EQ(watched->SyncToDisk(), OGRERR_NONE);
  ds->ExecuteSQL("CREATE TRIGGER audit AFTER INSERT ON watched BEGIN SELECT 1; END", nullptr, nullptr);
  EXPECT_EQ(GpkgRows::open(*ds, *watched, {}), nullptr);
  // A table with GDAL's spatial index: direct rows, unless its R-tree lacks its insert trigger
  // (then our rows would not be indexed) or the table has a trigger of someone else's.
  OGRLayer* indexed = ds->CreateLayer("indexed", &srs, wkbPolygon, nullptr);
  EXPECT_NE(GpkgRows::open(*ds, *indexed, {}), nullptr);
  OGRLayer* unindexed = ds->CreateLayer("unindexed", &srs, wkbPolygon, nullptr);
  ASSERT_EQ(unindexed->SyncToDisk(), OGRERR_NONE);
  ds->ExecuteSQL("DROP TRIGGER rtree_unindexed_geom_insert", nullptr, nullptr);
  EXPECT_EQ(GpkgRows::open(*ds, *unindexed, {}), nullptr);
  OGRLayer* audited = ds->CreateLayer("audited", &srs, wkbPolygon, nullptr);
  ASSERT_EQ(audited->SyncToDisk(), OGRERR_NONE);
  ds->ExecuteSQL("CREATE TRIGGER audit2 AFTER INSERT ON audited BEGIN SELECT 1; END", nullptr, nullptr);
  EXPECT_EQ(GpkgRows::open(*ds, *audited, {}), nullptr);
  // Not a GeoPackage.
  GDALDatasetUniquePtr memory(GetGDALDriverManager()->GetDriverByName("Memory")->Create("", 0, 0, 0, GDT_Unknown, nullptr));
  ASSERT_TRUE(memory);
  OGRLayer* in_memory = memory->CreateLayer("m", &srs, wkbPolygon, nullptr);
  EXPECT_EQ(GpkgRows::open(*memory, *in_memory, {}), nullptr);
}

TEST_F(VectorTest, UnknownLayerIsRefusedBeforeCreating) {
  const Scene scene = make_scene(3, 5, 1);
  const TempPath out("unknown.gpkg");
  VectorOptions options;
  options.layers = {"regions", "rivers"};
  try {
    write_vector(out.path, scene.labels(), scene.table, options);
    FAIL() << "no Interrupted";
  } catch (const WriteError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("'rivers'"), std::string::npos) << message;
    EXPECT_NE(message.find("regions, boundary_cells, voronoi_edges, cells"), std::string::npos) << message;
  }
  EXPECT_FALSE(std::filesystem::exists(out.path));
}

TEST_F(VectorTest, UnwritablePathAndUnknownDriver) {
  const Scene scene = make_scene(3, 5, 1);
  const std::string path = ::testing::TempDir() + "qtmv_no_such_dir/sub/out.gpkg";
  try {
    write_vector(path, scene.labels(), scene.table, VectorOptions{});
    FAIL() << "no Interrupted";
  } catch (const WriteError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(path, 0), 0u) << message;             // names the destination
    EXPECT_GT(message.size(), path.size() + 30) << message;       // and GDAL's reason
  }
  VectorOptions options;
  options.driver = "NoSuchDriver";
  EXPECT_THROW(write_vector(::testing::TempDir() + "qtmv_x.gpkg", scene.labels(), scene.table, options), WriteError);
  options.driver = "GTiff";  // raster only
  EXPECT_THROW(write_vector(::testing::TempDir() + "qtmv_x.tif", scene.labels(), scene.table, options), WriteError);
}

TEST_F(VectorTest, GdalFailureNamesTheLayer) {
  // The geometry column takes the name `code`: creating the field `code` then fails in GDAL.
  const Scene scene = make_scene(3, 5, 1);
  const TempPath out("gdal_failure.gpkg");
  VectorOptions options;
  options.layers = {"regions", "boundary_cells"};
  options.layer_options = {"GEOMETRY_NAME=code"};
  try {
    write_vector(out.path, scene.labels(), scene.table, options);
    FAIL() << "no Interrupted";
  } catch (const WriteError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(out.path + ", layer boundary_cells: ", 0), 0u) << message;
    EXPECT_NE(message.find("code"), std::string::npos) << message;
  }
}

TEST_F(VectorTest, Shapefiles) {
  const Scene scene = make_scene(4, 12, 9);
  const TempPath dir("shp");
  VectorOptions options;
  options.driver = "ESRI Shapefile";
  // A directory: one .shp per layer. The long source field name is truncated (a warning).
  write_vector(dir.path, scene.labels(), scene.table, options);
  auto ds = open_vector(dir.path);
  ASSERT_TRUE(ds);
  std::uint64_t flagged = 0;
  for (std::uint8_t b : scene.result.boundary) flagged += b;
  OGRLayer* boundary = ds->GetLayerByName("boundary_cells");
  ASSERT_NE(boundary, nullptr);
  EXPECT_EQ(static_cast<std::uint64_t>(boundary->GetFeatureCount()), flagged);
  OGRLayer* regions = ds->GetLayerByName("regions");
  ASSERT_NE(regions, nullptr);
  EXPECT_EQ(regions->GetFeatureCount(), scene.sites);
  EXPECT_GE(regions->GetLayerDefn()->GetFieldIndex("qtmv_cells"), 0);
  OGRLayer* edges = ds->GetLayerByName("voronoi_edges");
  ASSERT_NE(edges, nullptr);
  EXPECT_EQ(static_cast<std::size_t>(edges->GetFeatureCount()), neighbour_pairs(scene).size());
}

TEST_F(VectorTest, ProgressAndInterrupt) {
  const Scene scene = make_scene(6, 10, 2);
  const TempPath out("progress.gpkg");
  VectorOptions options;
  options.layers = {"regions", "boundary_cells", "voronoi_edges", "cells"};
  std::vector<double> seen;
  options.progress = [&](double fraction, const char* stage) {
    EXPECT_STREQ(stage, "write");
    seen.push_back(fraction);
    return true;
  };
  write_vector(out.path, scene.labels(), scene.table, options);
  ASSERT_GT(seen.size(), 10u);
  for (std::size_t k = 1; k < seen.size(); ++k) EXPECT_GE(seen[k], seen[k - 1]);
  EXPECT_EQ(seen.back(), 1.0);

  int calls = 0;
  options.progress = [&](double, const char*) { return ++calls < 5; };
  try {
    write_vector(out.path, scene.labels(), scene.table, options);
    FAIL() << "no Interrupted";
  } catch (const Interrupted&) {
    SUCCEED();  // a stop, not a failure
  }
  EXPECT_EQ(calls, 5);
}

}  // namespace
}  // namespace qtmv::write
