// Tile jobs that read only the sites near their tile (sites/tile_selection.hpp): for points,
// lines, polygons, composite layers and a projected CRS, the merge of N tiles equals the whole
// run byte for byte (CSV layers) at several levels and N; the tiles read fewer sites than N
// times the source; a source whose sites are far apart in places needs the reach widened; a
// source that cannot be selected from is read whole; the merge refuses a tile of other sites.
#include <gtest/gtest.h>

#include <cpl_conv.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "common/openmp_threads.hpp"
#include "qtmvoronoi_test_support.hpp"
#include "voronoi.hpp"

namespace qtmv {
namespace {

namespace fs = std::filesystem;

const std::string kTestdata = QTMV_TESTDATA_DIR;

/// A layer to write: its name, CRS and features as WKT (in that CRS), each with an "id" field.
struct LayerSpec {
  std::string name;
  std::string srs = "EPSG:4326";
  std::vector<std::string> wkt{};
  OGRwkbGeometryType type = wkbPoint;
};

/// Writes `layers` to a new GeoPackage at `path` (FIDs 1, 2, ... in the order given).
std::string write_gpkg(const std::string& path, const std::vector<LayerSpec>& layers) {
  GDALAllRegister();
  fs::remove(path);
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  GDALDatasetUniquePtr ds(driver->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  EXPECT_TRUE(ds) << path;
  for (const LayerSpec& spec : layers) {
    OGRSpatialReference srs;
    srs.SetFromUserInput(spec.srs.c_str());
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    OGRLayer* layer = ds->CreateLayer(spec.name.c_str(), &srs, spec.type, nullptr);
    OGRFieldDefn id("id", OFTInteger);
    layer->CreateField(&id);
    EXPECT_EQ(layer->StartTransaction(), OGRERR_NONE);
    int k = 0;
    for (const std::string& text : spec.wkt) {
      OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
      OGRGeometry* g = nullptr;
      OGRGeometryFactory::createFromWkt(text.c_str(), &srs, &g);
      f->SetGeometryDirectly(g);
      f->SetField("id", k++);
      EXPECT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE) << text;
    }
    EXPECT_EQ(layer->CommitTransaction(), OGRERR_NONE);
  }
  return path;
}

/// A point's WKT, with a CRS's coordinates from lon/lat (degrees) when `to` is given.
std::string point_wkt(double lon, double lat, OGRCoordinateTransformation* to = nullptr) {
  double x = lon, y = lat;
  if (to) to->Transform(1, &x, &y);
  std::ostringstream s;
  s.precision(17);
  s << "POINT (" << x << " " << y << ")";
  return s.str();
}

/// The country centres (testdata) as a GeoPackage: real, unevenly spread points.
std::string centres_gpkg(const std::string& dir) {
  std::ifstream in(kTestdata + "/country_centres.csv");
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = [&] {
    std::vector<std::string> h;
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) h.push_back(c);
    return h;
  }();
  const auto column = [&](const std::string& name) {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  LayerSpec spec{"centres"};
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
    if (cells.size() < header.size()) continue;
    spec.wkt.push_back(point_wkt(std::stod(cells[column("lon")]), std::stod(cells[column("lat")])));
  }
  return write_gpkg(dir + "/centres.gpkg", {spec});
}

/// `count` points spread evenly over the sphere (seeded).
std::vector<std::pair<double, double>> even_points(int count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0), lon(-180.0, 180.0);
  std::vector<std::pair<double, double>> out;
  for (int k = 0; k < count; ++k) out.emplace_back(lon(rng), std::asin(u(rng)) * 180.0 / M_PI);
  return out;
}

/// Random lines in lon/lat (none over 180 degrees of longitude between vertices).
std::vector<std::string> random_lines(int count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-175, 175), lat(-80, 80), step(-3, 3);
  std::vector<std::string> out;
  for (int k = 0; k < count; ++k) {
    double x = lon(rng), y = lat(rng);
    std::ostringstream s;
    s << "LINESTRING (" << x << " " << y;
    for (int v = 0; v < 4; ++v) {
      x = std::max(-180.0, std::min(180.0, x + step(rng)));
      y = std::max(-89.0, std::min(89.0, y + step(rng)));
      s << "," << x << " " << y;
    }
    s << ")";
    out.push_back(s.str());
  }
  return out;
}

/// A layer "projected" of `count` even points (seed `seed`) within `latitude` degrees of the equator,
/// in Web Mercator (EPSG:3857).
LayerSpec mercator_points(int count, unsigned seed, double latitude) {
  OGRSpatialReference wgs84, mercator;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  mercator.importFromEPSG(3857);
  std::unique_ptr<OGRCoordinateTransformation> to(OGRCreateCoordinateTransformation(&wgs84, &mercator));
  LayerSpec projected{"projected", "EPSG:3857"};
  for (const auto& [lon, lat] : even_points(count, seed)) {
    if (std::fabs(lat) < latitude) projected.wkt.push_back(point_wkt(lon, lat, to.get()));
  }
  return projected;
}

VoronoiOptions csv_options(int level) {
  VoronoiOptions o;
  o.level = level;
  o.device = "cpu";
  o.format = "CSV";
  o.kind = OutputKind::vector;
  o.vector.layers = {"regions", "voronoi_edges", "boundary_cells"};
  return o;
}

/// The bytes of `file`.
std::string contents_of(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// The bytes of each file of `dir`, by name.
std::map<std::string, std::string> contents(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    out[e.path().filename().string()] = contents_of(e.path().string());
  }
  return out;
}

/// What the tile jobs of one case read.
struct TilesRead {
  std::uint64_t whole_sites = 0;   ///< sites of the whole run
  std::uint64_t tile_sites = 0;    ///< sites the tile jobs read, summed
  int subset_tiles = 0;            ///< tiles whose read was a selection
  int most_rounds = 0;             ///< the most rounds of reading a tile's selection took
  std::vector<std::string> whole;  ///< why tiles read every site
};

/// Runs the whole run, N tile jobs and their merge of `source`; expects the merge's files to be
/// the whole run's, byte for byte; returns what the tiles read (from the read trace).
TilesRead expect_tiles_merge_into_whole(const std::string& source, const VoronoiOptions& options, int n) {
  SCOPED_TRACE(source + " level " + std::to_string(options.level) + ", " + std::to_string(n) + " tiles");
  const std::string dir = test::process_temp_dir() + "/sites_" + fs::path(source).stem().string() + "_L" +
                          std::to_string(options.level) + "_" + std::to_string(n);
  fs::remove_all(dir);
  fs::create_directories(dir + "/tiles");
  TilesRead read;
  read.whole_sites = run_voronoi(source, dir + "/whole", options).sites;
  CPLSetConfigOption("QTMV_TRACE", "read");
  // The sources here are small: selected all the same (unless a case asks for ALL).
  const bool all = CPLGetConfigOption("QTMV_TILE_SITES", nullptr) != nullptr;
  if (!all) CPLSetConfigOption("QTMV_TILE_SITES", "NEAR");
  for (int k = 1; k <= n; ++k) {
    VoronoiOptions tile = options;
    tile.tile_index = k;
    tile.tile_count = n;
    std::string trace;
    tile.messages = [&](Severity, const std::string& m) { trace += m + "\n"; };
    read.tile_sites += run_voronoi(source, dir + "/tiles/" + std::to_string(k) + ".qtmt", tile).sites;
    std::smatch m;
    if (std::regex_search(trace, m, std::regex("tile's sites: every feature read: ([^\n]*)"))) {
      read.whole.push_back(m[1]);
    } else if (std::regex_search(trace, m, std::regex("in ([0-9]+) rounds"))) {
      ++read.subset_tiles;
      read.most_rounds = std::max(read.most_rounds, std::stoi(m[1]));
    } else {
      ADD_FAILURE() << "no trace of the tile's sites: " << trace;
    }
    if (!read.whole.empty()) std::printf("tile %d/%d read every site: %s\n", k, n, read.whole.back().c_str());
  }
  CPLSetConfigOption("QTMV_TRACE", nullptr);
  if (!all) CPLSetConfigOption("QTMV_TILE_SITES", nullptr);
  VoronoiOptions merge = options;
  merge.merge = {dir + "/tiles"};
  run_voronoi(source, dir + "/merged", merge);
  const auto whole = contents(dir + "/whole"), merged = contents(dir + "/merged");
  EXPECT_EQ(whole.size(), 3u);
  EXPECT_EQ(merged.size(), whole.size());
  for (const auto& [name, bytes] : whole) {
    EXPECT_TRUE(merged.count(name) && merged.at(name) == bytes) << name << " differs from the whole run's";
  }
  return read;
}

TEST(TileSites, PointsReadNearTheirTileMergeIntoTheWholeRun) {
  const std::string dir = test::process_temp_dir();
  const std::string centres = centres_gpkg(dir);
  // Country centres are few and far apart over the oceans: each tile reads far around it (at
  // most this share of N times the sites).
  for (const auto& [level, n, share] : {std::tuple{7, 8, 0.35}, {10, 3, 0.75}, {9, 16, 0.25}}) {
    const TilesRead read = expect_tiles_merge_into_whole(centres, csv_options(level), n);
    EXPECT_EQ(read.subset_tiles, n);
    EXPECT_LT(read.tile_sites, share * n * read.whole_sites) << read.tile_sites << " sites read by " << n << " tiles";
    std::printf("country centres, level %d, %d tiles: %llu sites read of %llu\n", level, n,
                static_cast<unsigned long long>(read.tile_sites), static_cast<unsigned long long>(read.whole_sites));
  }
  VoronoiOptions cell = csv_options(8);
  cell.rule = label::Rule::cell;
  EXPECT_EQ(expect_tiles_merge_into_whole(centres, cell, 5).subset_tiles, 5);

  // Evenly spread points: N tiles read about the sites once in all.
  LayerSpec even{"even"};
  for (const auto& [lon, lat] : even_points(20000, 38)) even.wkt.push_back(point_wkt(lon, lat));
  const std::string path = write_gpkg(dir + "/even.gpkg", {even});
  const TilesRead read = expect_tiles_merge_into_whole(path, csv_options(9), 8);
  EXPECT_EQ(read.subset_tiles, 8);
  EXPECT_LE(read.tile_sites, read.whole_sites * 13 / 10) << read.tile_sites << " sites read by 8 tiles";
  std::printf("20000 even points, level 9, 8 tiles: %llu sites read\n", static_cast<unsigned long long>(read.tile_sites));
}

TEST(TileSites, LinesAndPolygonsReadNearTheirTileMergeIntoTheWholeRun) {
  const std::string dir = test::process_temp_dir();
  const std::string lines =
      write_gpkg(dir + "/lines.gpkg", {{"lines", "EPSG:4326", random_lines(300, 2026), wkbLineString}});
  // Lines and polygons are selected only where no edge is joined across +-180 (-wrap none).
  VoronoiOptions options = csv_options(8);
  options.read.wrap = sites::WrapMode::none;
  TilesRead read = expect_tiles_merge_into_whole(lines, options, 5);
  EXPECT_EQ(read.subset_tiles, 5);
  EXPECT_LT(read.tile_sites, read.whole_sites * 5 * 3 / 4);
  options.level = 10;
  read = expect_tiles_merge_into_whole(lines, options, 8);
  EXPECT_EQ(read.subset_tiles, 8);

  // The world's countries: -wrap none (their edges are not joined across +-180) lets the tiles
  // select; with -wrap auto they cross +-180 and every tile reads them all.
  const std::string countries = kTestdata + "/world_atlas_countries_110m.gpkg";
  options = csv_options(7);
  options.read.wrap = sites::WrapMode::none;
  read = expect_tiles_merge_into_whole(countries, options, 4);
  EXPECT_EQ(read.subset_tiles, 4);
  EXPECT_LT(read.tile_sites, read.whole_sites * 4);
  read = expect_tiles_merge_into_whole(countries, csv_options(7), 3);
  EXPECT_EQ(read.subset_tiles, 0);
  ASSERT_EQ(read.whole.size(), 3u);
  EXPECT_NE(read.whole[0].find("-wrap auto"), std::string::npos) << read.whole[0];
}

TEST(TileSites, CompositeLayersAndProjectedSourcesMergeIntoTheWholeRun) {
  const std::string dir = test::process_temp_dir();
  // Two layers (points and lines): site ids run over both, FIDs are each layer's own.
  LayerSpec points{"points"};
  for (const auto& [lon, lat] : even_points(3000, 7)) points.wkt.push_back(point_wkt(lon, lat));
  const std::string both =
      write_gpkg(dir + "/both.gpkg", {points, {"lines", "EPSG:4326", random_lines(200, 9), wkbLineString}});
  VoronoiOptions options = csv_options(8);
  options.read.layers = {"points", "lines"};
  options.read.wrap = sites::WrapMode::none;
  TilesRead read = expect_tiles_merge_into_whole(both, options, 6);
  EXPECT_EQ(read.subset_tiles, 6);
  EXPECT_LT(read.tile_sites, read.whole_sites * 2);
  options.read.where = "id % 3 <> 0";  // -where applies to the selection too
  read = expect_tiles_merge_into_whole(both, options, 4);
  EXPECT_EQ(read.subset_tiles, 4);

  // Points in Web Mercator (EPSG:3857, to +-85 degrees): the boxes are transformed to it; tiles
  // whose surroundings reach a pole, where it has no coordinates, read every point.
  const LayerSpec projected = mercator_points(5000, 11, 85);
  const std::string path = write_gpkg(dir + "/projected.gpkg", {projected});
  read = expect_tiles_merge_into_whole(path, csv_options(9), 16);
  EXPECT_GE(read.subset_tiles, 8);
  for (const std::string& why : read.whole) EXPECT_NE(why.find("CRS"), std::string::npos) << why;
  EXPECT_LT(read.tile_sites, read.whole_sites * 8);
}

TEST(TileSites, FarSitesWidenTheReachAndOthersAreReadWhole) {
  const std::string dir = test::process_temp_dir();
  // Many points in one small region, and a few far apart: the spacing of the whole misleads the
  // first reach of the empty places' caps, which then read farther.
  LayerSpec spec{"clustered"};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> dx(-3, 3);
  for (int k = 0; k < 4000; ++k) spec.wkt.push_back(point_wkt(10 + dx(rng), 45 + dx(rng)));
  for (const auto& [lon, lat] : even_points(12, 3)) spec.wkt.push_back(point_wkt(lon, lat));
  const std::string path = write_gpkg(dir + "/clustered.gpkg", {spec});
  const TilesRead read = expect_tiles_merge_into_whole(path, csv_options(8), 8);
  EXPECT_EQ(read.subset_tiles, 8);
  EXPECT_GE(read.most_rounds, 2);
  EXPECT_LT(read.tile_sites, read.whole_sites * 8);

  // A few features are read whole unless QTMV_TILE_SITES=NEAR.
  CPLSetConfigOption("QTMV_TRACE", "read");
  std::string trace;
  VoronoiOptions small = csv_options(7);
  small.tile_index = 1;
  small.tile_count = 2;
  small.messages = [&](Severity, const std::string& m) { trace += m + "\n"; };
  EXPECT_EQ(run_voronoi(path, dir + "/small.qtmt", small).sites, spec.wkt.size());
  CPLSetConfigOption("QTMV_TRACE", nullptr);
  EXPECT_NE(trace.find("every feature read: few features"), std::string::npos) << trace;

  // A CSV has no spatial index; -sql is read whole; so is everything under QTMV_TILE_SITES=ALL.
  VoronoiOptions options = csv_options(7);
  options.read.sql = "SELECT * FROM clustered WHERE id < 3000";
  EXPECT_EQ(expect_tiles_merge_into_whole(path, options, 3).whole, std::vector<std::string>(3, "-sql"));
  CPLSetConfigOption("QTMV_TILE_SITES", "ALL");
  const TilesRead all = expect_tiles_merge_into_whole(path, csv_options(7), 2);
  CPLSetConfigOption("QTMV_TILE_SITES", nullptr);
  EXPECT_EQ(all.whole, std::vector<std::string>(2, "QTMV_TILE_SITES=ALL"));
  EXPECT_EQ(all.tile_sites, 2 * all.whole_sites);
}

TEST(TileSites, AGeoPackagesReadsSpreadOverConnectionsSelectTheSameFeatures) {
  const std::string dir = test::test_dir();
  // Points (mostly in one box of a tile's surroundings: cut into pieces), lines, two layers with
  // -where, and points in a projected CRS: a tile job with 8 threads reads its boxes on several
  // connections, with 1 on the source's own, and both select the same features.
  LayerSpec points{"points"};
  for (const auto& [lon, lat] : even_points(20000, 5)) points.wkt.push_back(point_wkt(lon, lat));
  LayerSpec lines{"lines", "EPSG:4326", random_lines(300, 17), wkbLineString};
  const LayerSpec projected = mercator_points(12000, 23, 60);
  const std::string source = write_gpkg(dir + "/spread.gpkg", {points, lines, projected});
  VoronoiOptions base = csv_options(9);
  base.read.wrap = sites::WrapMode::none;
  VoronoiOptions composite = base;
  composite.read.layers = {"points", "lines"};
  composite.read.where = "id % 5 <> 2";
  VoronoiOptions mercator_points = base;
  mercator_points.read.layers = {"projected"};
  VoronoiOptions only_points = base;
  only_points.read.layers = {"points"};
  struct TraceRead {  // set for the test, unset however it ends
    TraceRead() { CPLSetConfigOption("QTMV_TRACE", "read"); }
    ~TraceRead() { CPLSetConfigOption("QTMV_TRACE", nullptr); }
  } trace_read;
  // Several connections where several threads are (a build without OpenMP has one).
  const bool spread = thread_count(8) > 1;
  for (const auto& [name, options] : {std::pair{"points", only_points}, {"composite", composite}, {"mercator", mercator_points}}) {
    for (const int k : {1, 4, 7}) {
      SCOPED_TRACE(std::string(name) + ", tile " + std::to_string(k) + "/8");
      std::string product[2];
      std::uint64_t sites[2] = {0, 0};
      for (const int threads : {1, 8}) {
        VoronoiOptions t = options;
        t.tile_index = k;
        t.tile_count = 8;
        t.threads = threads;
        std::string trace;
        t.messages = [&](Severity, const std::string& m) { trace += m + "\n"; };
        const std::string out = dir + "/" + name + std::to_string(k) + "_" + std::to_string(threads) + ".qtmt";
        sites[threads > 1] = run_voronoi(source, out, t).sites;
        product[threads > 1] = contents_of(out);
        std::smatch m;
        ASSERT_TRUE(std::regex_search(trace, m, std::regex("filtered reads in [0-9]+ rounds on ([0-9]+) connection"))) << trace;
        if (threads == 1 || !spread) {
          EXPECT_EQ(m[1], "1") << trace;
        } else {
          EXPECT_GT(std::stoi(m[1]), 1) << trace;
        }
      }
      EXPECT_EQ(sites[0], sites[1]);
      EXPECT_GT(sites[0], 0u);
      EXPECT_TRUE(!product[0].empty() && product[0] == product[1]) << "the tile products differ";
    }
  }
}

TEST(TileSites, MergeRefusesTilesOfOtherSitesOrOldVersions) {
  const std::string dir = test::test_dir();
  LayerSpec spec{"points"};
  for (const auto& [lon, lat] : even_points(2000, 21)) spec.wkt.push_back(point_wkt(lon, lat));
  const std::string path = write_gpkg(dir + "/points.gpkg", {spec});
  const VoronoiOptions options = csv_options(7);
  const auto tile = [&](int k, const VoronoiOptions& o, const std::string& name) {
    VoronoiOptions t = o;
    t.tile_index = k;
    t.tile_count = 3;
    const bool all = CPLGetConfigOption("QTMV_TILE_SITES", nullptr) != nullptr;
    if (!all) CPLSetConfigOption("QTMV_TILE_SITES", "NEAR");  // a small source
    run_voronoi(path, dir + "/" + name, t);
    if (!all) CPLSetConfigOption("QTMV_TILE_SITES", nullptr);
    return dir + "/" + name;
  };
  const std::string t1 = tile(1, options, "1.qtmt"), t3 = tile(3, options, "3.qtmt");
  // The selection and its product do not depend on the threads.
  VoronoiOptions one_thread = options;
  one_thread.threads = 1;
  EXPECT_EQ(contents_of(tile(1, one_thread, "1t.qtmt")), contents_of(t1));
  VoronoiOptions other = options;
  other.read.where = "id > 10";
  const std::string other2 = tile(2, other, "other2.qtmt");
  // A tile whose sites were all read (QTMV_TILE_SITES=ALL) joins selected ones.
  CPLSetConfigOption("QTMV_TILE_SITES", "ALL");
  const std::string all2 = tile(2, options, "all2.qtmt");
  CPLSetConfigOption("QTMV_TILE_SITES", nullptr);
  VoronoiOptions merge = options;
  // The merge of `tiles` fails naming `file` and saying `why`.
  const auto refused = [&](const std::vector<std::string>& tiles, const std::string& file, const std::string& why) {
    merge.merge = tiles;
    try {
      run_voronoi(path, dir + "/refused", merge);
      ADD_FAILURE() << file << " merged";
    } catch (const VoronoiError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir + "/refused"));
  };
  refused({t1, other2, t3}, other2, "other sites");
  merge.merge = {t1, all2, t3};
  EXPECT_NO_THROW(run_voronoi(path, dir + "/out", merge));

  // A version 1 product (before tiles listed their sites) is refused, saying so.
  std::string bytes = contents_of(t1);
  bytes[8] = 1;
  const std::string old = dir + "/old.qtmt";
  std::ofstream(old, std::ios::binary) << bytes;
  refused({old, all2, t3}, old, "version 1");
}

}  // namespace
}  // namespace qtmv
