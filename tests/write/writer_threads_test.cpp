// The vector writer on all cores: every layer's rows and R-tree (every node, the rowid and parent
// tables) are the same bytes with 1 and several threads, and the same as the writer's before it
// made its work ahead on all cores (the digests below, recorded from that writer); SQLite's
// integrity_check and rtreecheck() pass and every window query finds what a scan finds; other
// drivers, written through OGR, get the same file whatever the threads.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "../test_temp_dir.hpp"
#include "common/openmp_threads.hpp"
#include "label/labeller.hpp"
#include "label/synthetic_sites.hpp"
#include "sqlite_rows.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::write {
namespace {

/// Sites at random points (and one that loses every tie: no cell, an empty region), labelled at
/// `level`, with a source of two fields.
struct Scene {
  int level = 0;
  label::LabelResult result;
  sites::SiteTable table;

  CellLabels labels() const { return {level, result.site.data(), result.distance_m.data(), result.boundary.data()}; }
};

Scene make_scene(int level, int points, unsigned seed) {
  Scene scene;
  scene.level = level;
  label::SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-1, 1);
  std::vector<std::pair<double, double>> at{{179.95, 3}, {-179.95, -3}, {0, 89.9}, {0, -89.9}};
  for (int k = 0; k < points; ++k) at.push_back({lon(rng), std::asin(z(rng)) / grid::kDegree});
  at.push_back(at[5]);
  for (std::size_t s = 0; s < at.size(); ++s) label::add_point(g, at[s].first, at[s].second, static_cast<int>(s));
  label::LabelOptions options;
  options.device = "cpu";
  scene.result = label::label_all(g.input(), options);
  auto* definition = new OGRFeatureDefn("source");
  OGRFieldDefn name("name", OFTString), pop("pop", OFTInteger64);
  definition->AddFieldDefn(&name);
  definition->AddFieldDefn(&pop);
  scene.table.set_source(definition, "memory", "source");
  for (std::size_t s = 0; s < at.size(); ++s) {
    sites::SiteRecord record;
    record.fid = 10 + static_cast<std::int64_t>(s);
    record.attributes.reset(OGRFeature::CreateFeature(definition));
    record.attributes->SetField("name", ("site " + std::to_string(s)).c_str());
    record.attributes->SetField("pop", static_cast<GIntBig>(3 * s));
    record.kind = sites::kPointSite;
    scene.table.sites.push_back(std::move(record));
  }
  return scene;
}

constexpr const char* kLayers[] = {"regions", "boundary_cells", "voronoi_edges", "cells"};

/// The file written with `threads` threads (all four layers unless `layers` says, each with a
/// spatial index in a GeoPackage).
std::string write_with(const Scene& scene, int threads, const std::string& driver, const std::string& name,
                       std::vector<std::string> layers = {std::begin(kLayers), std::end(kLayers)}) {
  const std::string path = qtmv::test::process_temp_dir() + "/threads_" + name;
  std::filesystem::remove_all(path);
  VectorOptions options;
  options.driver = driver;
  options.layers = std::move(layers);
  if (driver == "GPKG") options.layer_options = {"SPATIAL_INDEX=YES"};
  const ScopedDefaultThreads team(threads);
  write_vector(path, scene.labels(), scene.table, options);
  return path;
}

std::vector<std::string> rows(sqlite3* db, const std::string& sql) { return test::sqlite_rows(db, sql); }

/// FNV-1a of the lines.
std::uint64_t digest(const std::vector<std::string>& lines) {
  std::uint64_t h = 1469598103934665603ull;
  for (const std::string& line : lines) {
    for (const char c : line + "\n") h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  }
  return h;
}

/// Per layer, what the writer put in the GeoPackage: the table's rows, then the R-tree's nodes,
/// rowid and parent tables, byte for byte.
std::vector<std::vector<std::string>> layer_dumps(const std::string& path) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << path;
  std::vector<std::vector<std::string>> out;
  for (const char* layer : kLayers) {
    std::vector<std::string> dump = rows(db, std::string("SELECT * FROM \"") + layer + "\" ORDER BY fid");
    const std::string rtree = std::string("rtree_") + layer + "_geom";
    for (const auto& [table, key] : {std::pair{"_node", "nodeno"}, {"_rowid", "rowid"}, {"_parent", "nodeno"}}) {
      const std::vector<std::string> more = rows(db, "SELECT * FROM \"" + rtree + table + "\" ORDER BY " + key);
      dump.insert(dump.end(), more.begin(), more.end());
    }
    out.push_back(dump);
  }
  sqlite3_close(db);
  return out;
}

class WriterThreadsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { GDALAllRegister(); }
};

TEST_F(WriterThreadsTest, GeoPackageRowsAndRTreesAreTheSameBytesWithAnyThreads) {
  // Level 7 (131 072 cells): the cells in 2 blocks, the regions in 2, R-trees of three levels.
  const Scene scene = make_scene(7, 2500, 37);
  const auto one = layer_dumps(write_with(scene, 1, "GPKG", "1.gpkg"));
  for (int threads : {2, 5}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    const auto several = layer_dumps(write_with(scene, threads, "GPKG", std::to_string(threads) + ".gpkg"));
    for (std::size_t l = 0; l < std::size(kLayers); ++l) EXPECT_EQ(several[l], one[l]) << kLayers[l];
  }
  // The writer before this one's work ahead (main at c0fe02c) wrote these, on any thread count.
  const std::uint64_t before[] = {0x0f7f9f5d402cac0aull, 0x2a3138480fdf6b76ull, 0x8e301b2f2ecda22aull, 0xdbe97d9ca7a5f081ull};
  for (std::size_t l = 0; l < std::size(kLayers); ++l) {
    EXPECT_EQ(digest(one[l]), before[l]) << kLayers[l] << ": 0x" << std::hex << digest(one[l]);
  }
}

TEST_F(WriterThreadsTest, RTreesPassSqlitesChecksAndFindWhatAScanFinds) {
  const Scene scene = make_scene(7, 2500, 41);
  const std::string path = write_with(scene, 3, "GPKG", "checked.gpkg");
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  EXPECT_EQ(rows(db, "PRAGMA integrity_check"), std::vector<std::string>{" tok"});
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90), size(0, 30);
  for (const char* layer : kLayers) {
    SCOPED_TRACE(layer);
    const std::string rtree = std::string("rtree_") + layer + "_geom";
    EXPECT_EQ(rows(db, "SELECT rtreecheck('" + rtree + "')"), std::vector<std::string>{" tok"});
    // Each row's envelope, from its blob's header (its rtree entry holds it: float32 outward).
    struct Box {
      std::int64_t fid;
      double min_x, max_x, min_y, max_y;
    };
    std::vector<Box> boxes;
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, (std::string("SELECT fid, geom FROM \"") + layer + "\"").c_str(), -1, &st, nullptr), SQLITE_OK);
    while (sqlite3_step(st) == SQLITE_ROW) {
      const auto* blob = static_cast<const unsigned char*>(sqlite3_column_blob(st, 1));
      if (sqlite3_column_bytes(st, 1) < 40 || (blob[3] & 0x10) != 0) continue;  // empty
      Box b{sqlite3_column_int64(st, 0), 0, 0, 0, 0};
      std::memcpy(&b.min_x, blob + 8, 32);  // little-endian, as the host
      boxes.push_back(b);
    }
    sqlite3_finalize(st);
    EXPECT_EQ(rows(db, "SELECT count(*) FROM \"" + rtree + "\""), std::vector<std::string>{" i" + std::to_string(boxes.size())})
        << "an entry per non-empty row";
    for (int w = 0; w < 40; ++w) {
      const double x = lon(rng), y = lat(rng), x2 = std::min(180.0, x + size(rng)), y2 = std::min(90.0, y + size(rng) / 2);
      char sql[256];
      std::snprintf(sql, sizeof sql, "SELECT id FROM \"%s\" WHERE maxx >= %.17g AND minx <= %.17g AND maxy >= %.17g AND miny <= %.17g",
                    rtree.c_str(), x, x2, y, y2);
      const std::vector<std::string> found = rows(db, sql);
      const std::set<std::string> tree(found.begin(), found.end());
      for (const Box& b : boxes) {
        if (b.max_x >= x && b.min_x <= x2 && b.max_y >= y && b.min_y <= y2) {
          EXPECT_TRUE(tree.count(" i" + std::to_string(b.fid))) << sql << ": row " << b.fid << " not found";
        }
      }
    }
  }
  sqlite3_close(db);
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST_F(WriterThreadsTest, OgrDriversGetTheSameFileWithAnyThreads) {
  // Through OGR features (geometries made ahead on all cores): a directory of Shapefiles and one
  // of FlatGeobuf files (every layer), a GeoJSON file (regions).
  const Scene scene = make_scene(6, 300, 43);
  CPLPushErrorHandler(CPLQuietErrorHandler);  // FlatGeobuf's warning for the empty region's row
  for (const std::string driver : {"ESRI Shapefile", "FlatGeobuf", "GeoJSON"}) {
    SCOPED_TRACE(driver);
    const bool one_layer = driver == "GeoJSON";
    const std::vector<std::string> layers = one_layer ? std::vector<std::string>{"regions"}
                                                      : std::vector<std::string>{std::begin(kLayers), std::end(kLayers)};
    const std::string name = driver.substr(0, 4) + (one_layer ? ".geojson" : "");
    const std::string one = write_with(scene, 1, driver, name + "_1", layers);
    const std::string several = write_with(scene, 4, driver, name + "_4", layers);
    std::vector<std::pair<std::string, std::string>> files;  // (one's, several's)
    if (one_layer) {
      files.emplace_back(one, several);
    } else {
      for (const auto& entry : std::filesystem::directory_iterator(one)) {
        files.emplace_back(entry.path().string(), several + "/" + entry.path().filename().string());
      }
      EXPECT_GE(files.size(), std::size(kLayers));
    }
    for (const auto& [a, b] : files) {
      const std::string bytes = file_bytes(a);
      EXPECT_GT(bytes.size(), 100u) << a;
      EXPECT_EQ(file_bytes(b), bytes) << a;
    }
  }
  CPLPopErrorHandler();
}

}  // namespace
}  // namespace qtmv::write
