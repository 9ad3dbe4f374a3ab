// Partitioned output (-tile K/N -part, then -merge PARTS -of VRT): the parts, dissolved by
// site_fid, are the whole run's regions (the same cells per site, areas summing to the whole
// run's to 1e-9, the same geometry: GEOS's union of a site's parts against its region leaves no
// area); the per-cell layers' rows are the whole run's; the index opens as one dataset with the
// parts' rows; and every bad set of parts is refused naming the file, writing nothing.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <ogrsf_frmts.h>

#include "parts_test_support.hpp"
#include "qtmvoronoi_test_support.hpp"
#include "voronoi.hpp"

namespace qtmv {
namespace {

namespace fs = std::filesystem;
using test::expect_index_refused;
using test::run_index;

const std::string kTestdata = QTMV_TESTDATA_DIR;
const std::string kCentres = kTestdata + "/country_centres.csv";

VoronoiOptions centres_options(int level, const std::vector<std::string>& layers) {
  VoronoiOptions o;
  o.level = level;
  o.device = "cpu";
  o.kind = OutputKind::vector;
  o.vector.layers = layers;
  o.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  o.read.source_srs = "EPSG:4326";
  return o;
}

/// Tile jobs k = 1..n (those of `which`, all when empty) writing parts dir/k.gpkg.
void run_parts(const VoronoiOptions& options, int n, const std::string& dir, const std::vector<int>& which = {}) {
  test::run_parts(kCentres, options, n, dir, "gpkg", which);
}

/// A region as read: its cells, area and geometry (several rows of one site: their sums and union).
struct SiteRegion {
  std::int64_t cells = 0;
  double area = 0;
  int rows = 0;
  std::vector<std::unique_ptr<OGRGeometry>> pieces;
};

std::map<std::int64_t, SiteRegion> regions_of(const std::string& path) {
  const GDALDatasetUniquePtr ds = test::open_dataset(path, GDAL_OF_VECTOR);
  EXPECT_TRUE(ds) << path;
  std::map<std::int64_t, SiteRegion> out;
  if (!ds) return out;
  OGRLayer* layer = ds->GetLayerByName("regions");
  EXPECT_TRUE(layer) << path;
  if (!layer) return out;
  for (auto& feature : *layer) {
    SiteRegion& r = out[feature->GetFieldAsInteger64("site_fid")];
    r.cells += feature->GetFieldAsInteger64("cells");
    r.area += feature->GetFieldAsDouble("area_m2");
    ++r.rows;
    const OGRGeometry* g = feature->GetGeometryRef();
    if (g && !g->IsEmpty()) r.pieces.emplace_back(g->clone());
  }
  return out;
}

/// The union of a site's pieces (GEOS through OGR).
std::unique_ptr<OGRGeometry> dissolved(const SiteRegion& r) {
  OGRMultiPolygon all;
  for (const auto& piece : r.pieces) {
    const OGRwkbGeometryType type = wkbFlatten(piece->getGeometryType());
    if (type == wkbMultiPolygon) {
      for (const OGRPolygon* p : *piece->toMultiPolygon()) all.addGeometry(p);
    } else {
      all.addGeometry(piece.get());
    }
  }
  return std::unique_ptr<OGRGeometry>(all.UnionCascaded());
}

/// The rows of a per-cell layer: code -> site_fid.
std::map<std::int64_t, std::int64_t> cell_rows(const std::string& path, const char* name) {
  std::map<std::int64_t, std::int64_t> out;
  const GDALDatasetUniquePtr ds = test::open_dataset(path, GDAL_OF_VECTOR);
  OGRLayer* layer = ds ? ds->GetLayerByName(name) : nullptr;
  EXPECT_TRUE(layer) << path << " " << name;
  if (!layer) return out;
  for (auto& feature : *layer) {
    const bool fresh = out.emplace(feature->GetFieldAsInteger64("code"), feature->GetFieldAsInteger64("site_fid")).second;
    EXPECT_TRUE(fresh) << name << ": code " << feature->GetFieldAsInteger64("code") << " twice";
  }
  return out;
}

std::uint64_t feature_count(const std::string& path, const char* name) {
  const GDALDatasetUniquePtr ds = test::open_dataset(path, GDAL_OF_VECTOR);
  OGRLayer* layer = ds ? ds->GetLayerByName(name) : nullptr;
  return layer ? static_cast<std::uint64_t>(layer->GetFeatureCount(TRUE)) : 0;
}

void expect_parts_are_the_whole_run(int level, int tiles, const std::vector<std::string>& layers) {
  SCOPED_TRACE("level " + std::to_string(level) + ", " + std::to_string(tiles) + " tiles");
  const std::string dir = test::process_temp_dir() + "/parts_L" + std::to_string(level) + "_" + std::to_string(tiles);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const VoronoiOptions options = centres_options(level, layers);
  run_voronoi(kCentres, dir + "/whole.gpkg", options);
  run_parts(options, tiles, dir + "/parts");
  const VoronoiSummary summary = run_index({dir + "/parts"}, dir + "/index.vrt");
  EXPECT_EQ(summary.device, "index of " + std::to_string(tiles) + " parts");

  // The index is one dataset over the parts: its regions are the parts' rows.
  const auto whole = regions_of(dir + "/whole.gpkg");
  const auto parts = regions_of(dir + "/index.vrt");
  std::uint64_t part_rows = 0;
  for (int k = 1; k <= tiles; ++k) part_rows += feature_count(dir + "/parts/" + std::to_string(k) + ".gpkg", "regions");
  EXPECT_EQ(feature_count(dir + "/index.vrt", "regions"), part_rows);
  int split = 0;
  for (const auto& [fid, r] : parts) split += r.rows > 1 ? 1 : 0;
  EXPECT_GT(split, 0) << "no region is cut at a tile's edge";

  // Dissolved by site_fid: the whole run's regions (sites without a cell have no part).
  std::size_t with_cells = 0;
  for (const auto& [fid, region] : whole) {
    if (region.cells == 0) {
      EXPECT_EQ(parts.count(fid), 0u) << "site " << fid << " has no cell but a part";
      continue;
    }
    ++with_cells;
    ASSERT_EQ(parts.count(fid), 1u) << "site " << fid;
    const SiteRegion& part = parts.at(fid);
    EXPECT_EQ(part.cells, region.cells) << "site " << fid;
    EXPECT_NEAR(part.area, region.area, 1e-9 * region.area) << "site " << fid;
    ASSERT_EQ(region.pieces.size(), 1u);
    const std::unique_ptr<OGRGeometry> joined = dissolved(part);
    ASSERT_TRUE(joined) << "site " << fid;
    const std::unique_ptr<OGRGeometry> difference(joined->SymDifference(region.pieces[0].get()));
    ASSERT_TRUE(difference) << "site " << fid;
    const double area = difference->IsEmpty() ? 0.0 : OGR_G_Area(OGRGeometry::ToHandle(difference.get()));
    EXPECT_LT(area, 1e-9) << "site " << fid << ": the parts' union differs from the region by " << area
                          << " square degrees";
  }
  EXPECT_EQ(parts.size(), with_cells);

  // The per-cell layers: the whole run's rows, each once.
  for (const char* name : {"boundary_cells", "cells"}) {
    if (std::find(layers.begin(), layers.end(), name) == layers.end()) continue;
    const auto single = cell_rows(dir + "/whole.gpkg", name);
    const auto indexed = cell_rows(dir + "/index.vrt", name);
    EXPECT_EQ(indexed.size(), single.size()) << name;
    EXPECT_TRUE(indexed == single) << name << ": the parts' rows are not the whole run's";
  }
}

TEST(PartitionedOutput, PartsDissolveIntoTheWholeRun) {
  expect_parts_are_the_whole_run(5, 3, {"regions", "boundary_cells", "cells"});
  expect_parts_are_the_whole_run(7, 8, {"regions", "boundary_cells"});
  expect_parts_are_the_whole_run(8, 5, {"regions"});
}

TEST(PartitionedOutput, BadPartSetsAreRefusedNamingTheFile) {
  const std::string dir = test::test_dir();
  const VoronoiOptions options = centres_options(5, {"regions", "boundary_cells"});
  run_parts(options, 4, dir + "/four");
  run_parts(options, 2, dir + "/two", {2});
  const std::string p1 = dir + "/four/1.gpkg", p2 = dir + "/four/2.gpkg", p3 = dir + "/four/3.gpkg",
                    p4 = dir + "/four/4.gpkg";
  const std::string index = dir + "/index.vrt";
  expect_index_refused({p1, p2, p4}, {"1 of the 4 parts missing (tile 3)"}, index);
  expect_index_refused({dir + "/four", p2}, {p2, "tile 2/4 again"}, index);
  expect_index_refused({p1, p2, dir + "/two/2.gpkg", p4}, {dir + "/two/2.gpkg", "one split"}, index);
  fs::create_directories(dir + "/empty");
  expect_index_refused({dir + "/empty"}, {dir + "/empty", "without parts"}, index);

  // A whole run's GeoPackage is not a part; nor are parts of another level or with other layers.
  VoronoiOptions other = options;
  run_voronoi(kCentres, dir + "/whole.gpkg", other);
  expect_index_refused({p1, p2, dir + "/whole.gpkg", p4}, {dir + "/whole.gpkg", "not a part"}, index);
  other.level = 6;
  run_parts(other, 4, dir + "/level6", {3});
  expect_index_refused({p1, p2, dir + "/level6/3.gpkg", p4}, {dir + "/level6/3.gpkg", "level 6"}, index);
  other = options;
  other.vector.layers = {"regions"};
  run_parts(other, 4, dir + "/regions_only", {3});
  expect_index_refused({p1, p2, dir + "/regions_only/3.gpkg", p4}, {dir + "/regions_only/3.gpkg", "same -layers"},
                       index);
  other = options;
  other.read.where = "lon > 0";
  run_parts(other, 4, dir + "/east", {3});
  expect_index_refused({p1, p2, dir + "/east/3.gpkg", p4}, {dir + "/east/3.gpkg", "read with other options"}, index);
  // Another source, or the same one changed after the first parts were written.
  const std::string copy = dir + "/centres.csv";
  fs::copy_file(kCentres, copy);
  other = options;
  other.part = true;
  other.tile_index = 3;
  other.tile_count = 4;
  run_voronoi(copy, dir + "/copy3.gpkg", other);
  expect_index_refused({p1, p2, dir + "/copy3.gpkg", p4}, {dir + "/copy3.gpkg", "a part of '" + copy + "'"}, index);
  other.tile_index = 4;
  fs::last_write_time(copy, fs::last_write_time(copy) + std::chrono::seconds(10));
  run_voronoi(copy, dir + "/copy4.gpkg", other);
  expect_index_refused({dir + "/copy4.gpkg", dir + "/copy3.gpkg"}, {dir + "/copy3.gpkg", "after it changed"}, index);

  // The good ones index; relative paths: the index moved with its parts still opens.
  EXPECT_NO_THROW(run_index({dir + "/four"}, index));
  fs::create_directories(dir + "/moved");
  fs::rename(dir + "/four", dir + "/moved/four");
  fs::rename(index, dir + "/moved/index.vrt");
  EXPECT_EQ(feature_count(dir + "/moved/index.vrt", "boundary_cells"),
            feature_count(dir + "/whole.gpkg", "boundary_cells"));
}

// What a part cannot be is refused before any work, naming the reason.
TEST(PartitionedOutput, PartsRefuseWhatCannotBeCut) {
  const std::string dir = test::test_dir();
  VoronoiOptions options = centres_options(5, {"regions", "voronoi_edges"});
  options.part = true;
  options.tile_index = 1;
  options.tile_count = 2;
  const auto refused = [&](const VoronoiOptions& o, const std::string& destination, const std::string& says) {
    try {
      run_voronoi(kCentres, destination, o);
      ADD_FAILURE() << "accepted: " << says;
    } catch (const VoronoiError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(destination));
  };
  refused(options, dir + "/p.gpkg", "no voronoi_edges layer");
  options.vector.layers = {"regions"};
  refused(options, dir + "/p.fgb", "a part is a GeoPackage");
  // (A raster destination is a raster part: raster_parts_test.cpp.)
  VoronoiOptions whole = options;
  whole.tile_count = whole.tile_index = 0;
  refused(whole, dir + "/w.gpkg", "give -tile K/N");
}

// The command line: -part needs -tile; an index reads no source.
TEST(PartitionedOutput, CommandLine) {
  const std::string dir = test::test_dir();
  const std::vector<std::string> csv = {"-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-level", "5"};
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"-part", kCentres, dir + "/p.gpkg"}, "-part is for a tile job"},
      {{"-merge", dir, "-of", "VRT", kCentres, dir + "/p.vrt"}, "reads no source"},
  };
  for (const Case& c : cases) {
    const test::ProcessResult r = test::run_qtmvoronoi(test::concat(csv, c.args));
    EXPECT_EQ(r.status, 2) << c.says;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
  }
  // Without -layers a part holds regions and boundary_cells; the index of one part is a dataset.
  test::ProcessResult r = test::run_qtmvoronoi(test::concat(csv, {"-q", "-tile", "1/1", "-part", kCentres, dir + "/1.gpkg"}));
  ASSERT_EQ(r.status, 0) << r.err;
  r = test::run_qtmvoronoi({"-q", "-merge", dir + "/1.gpkg", dir + "/index.vrt"});
  ASSERT_EQ(r.status, 0) << r.err;
  const GDALDatasetUniquePtr ds = test::open_dataset(dir + "/index.vrt", GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  EXPECT_EQ(ds->GetLayerCount(), 2);
  EXPECT_TRUE(ds->GetLayerByName("regions"));
  EXPECT_TRUE(ds->GetLayerByName("boundary_cells"));
}

}  // namespace
}  // namespace qtmv
