// Tile jobs and their merge (-tile K/N, -merge): the merged output equals the whole run's, byte
// for byte (CSV layers), for points, lines and polygons at levels 7-10 and for both distance
// rules; and every way a merge can be given bad tile products fails naming the file, writing
// nothing.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "qtmvoronoi_test_support.hpp"
#include "voronoi.hpp"

namespace qtmv {
namespace {

namespace fs = std::filesystem;

const std::string kTestdata = QTMV_TESTDATA_DIR;
const std::string kCentres = kTestdata + "/country_centres.csv";
const std::string kCountries = kTestdata + "/world_atlas_countries_110m.gpkg";

/// The options of every run of a case: CPU, three CSV layers (a directory of CSV files).
VoronoiOptions case_options(const std::string& source, int level, label::Rule rule = label::Rule::exact) {
  VoronoiOptions o;
  o.level = level;
  o.rule = rule;
  o.device = "cpu";
  o.format = "CSV";
  o.kind = OutputKind::vector;
  o.vector.layers = {"regions", "voronoi_edges", "boundary_cells"};
  if (source == kCentres) {
    o.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
    o.read.source_srs = "EPSG:4326";
  }
  return o;
}

/// Runs tile jobs k = 1..n (those of `which`, all when empty) into dir/k.qtmt.
void run_tiles(const std::string& source, VoronoiOptions options, int n, const std::string& dir,
               const std::vector<int>& which = {}) {
  fs::create_directories(dir);
  for (int k = 1; k <= n; ++k) {
    if (!which.empty() && std::find(which.begin(), which.end(), k) == which.end()) continue;
    options.tile_index = k;
    options.tile_count = n;
    run_voronoi(source, dir + "/" + std::to_string(k) + ".qtmt", options);
  }
}

/// Every file of a directory, by name, with its bytes.
std::map<std::string, std::string> files_of(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    out[e.path().filename().string()] = bytes.str();
  }
  return out;
}

/// A CSV of WKT line strings: random lines, one across +-180 and one up a meridian to the pole.
std::string lines_csv(const std::string& dir) {
  const std::string path = dir + "/lines.csv";
  std::ofstream f(path);
  f << "WKT,id\n";
  f << "\"LINESTRING (170 10,-170 12,-160 20)\",0\n";
  f << "\"LINESTRING (20 60,20 80,20 90)\",1\n";
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-80, 80), step(-6, 6);
  for (int k = 2; k < 40; ++k) {
    double x = lon(rng), y = lat(rng);
    f << "\"LINESTRING (" << x << " " << y;
    for (int v = 0; v < 4; ++v) {
      x = std::max(-180.0, std::min(180.0, x + step(rng)));
      y = std::max(-89.0, std::min(89.0, y + step(rng)));
      f << "," << x << " " << y;
    }
    f << ")\"," << k << "\n";
  }
  return path;
}

void expect_merge_is_the_whole_run(const std::string& source, const VoronoiOptions& options, int tiles) {
  SCOPED_TRACE(source + " level " + std::to_string(options.level) + ", " + std::to_string(tiles) + " tiles");
  const std::string dir = test::process_temp_dir() + "/" + fs::path(source).stem().string() + "_L" +
                          std::to_string(options.level) + "_" + std::to_string(tiles);
  fs::remove_all(dir);
  fs::create_directories(dir);
  run_voronoi(source, dir + "/whole", options);
  run_tiles(source, options, tiles, dir + "/tiles");
  VoronoiOptions merge = options;
  merge.merge = {dir + "/tiles"};
  const VoronoiSummary summary = run_voronoi(source, dir + "/merged", merge);
  EXPECT_NE(summary.device.find("merged " + std::to_string(tiles) + " tile products"), std::string::npos)
      << summary.device;
  const auto whole = files_of(dir + "/whole"), merged = files_of(dir + "/merged");
  ASSERT_EQ(whole.size(), 3u);
  ASSERT_EQ(merged.size(), whole.size());
  for (const auto& [name, bytes] : whole) {
    ASSERT_TRUE(merged.count(name)) << name;
    EXPECT_TRUE(merged.at(name) == bytes) << name << " differs (" << merged.at(name).size() << " bytes, whole run "
                                          << bytes.size() << ")";
  }
}

TEST(TileMerge, PointsMergeIntoTheWholeRun) {
  expect_merge_is_the_whole_run(kCentres, case_options(kCentres, 7), 8);
  expect_merge_is_the_whole_run(kCentres, case_options(kCentres, 10), 3);
  expect_merge_is_the_whole_run(kCentres, case_options(kCentres, 8, label::Rule::cell), 5);
}

TEST(TileMerge, LinesMergeIntoTheWholeRun) {
  const std::string source = lines_csv(test::process_temp_dir());  // test_dir() is cleared per case
  expect_merge_is_the_whole_run(source, case_options(source, 8), 5);
  expect_merge_is_the_whole_run(source, case_options(source, 9), 16);
}

TEST(TileMerge, PolygonsMergeIntoTheWholeRun) {
  expect_merge_is_the_whole_run(kCountries, case_options(kCountries, 7), 4);
  expect_merge_is_the_whole_run(kCountries, case_options(kCountries, 10), 3);
}

/// Expects the merge of `paths` to fail with a message holding every one of `words`, and the
/// destination not to exist.
void expect_merge_refused(const std::vector<std::string>& paths, const VoronoiOptions& options,
                          const std::vector<std::string>& words, const std::string& destination) {
  VoronoiOptions merge = options;
  merge.merge = paths;
  try {
    run_voronoi(kCentres, destination, merge);
    ADD_FAILURE() << "merge accepted; expected: " << words.front();
  } catch (const VoronoiError& e) {
    for (const std::string& w : words) EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(destination)) << destination;
}

TEST(TileMerge, BadTileProductsAreRefusedNamingTheFile) {
  const std::string dir = test::test_dir();
  const VoronoiOptions options = case_options(kCentres, 6);
  run_tiles(kCentres, options, 4, dir + "/four");
  run_tiles(kCentres, options, 2, dir + "/two");
  const std::string t1 = dir + "/four/1.qtmt", t2 = dir + "/four/2.qtmt", t3 = dir + "/four/3.qtmt",
                    t4 = dir + "/four/4.qtmt";
  const std::string out = dir + "/out";

  expect_merge_refused({t1, t2, t4}, options, {"1 of the 4 tiles missing (3)"}, out);
  expect_merge_refused({dir + "/four", t2}, options, {t2, "tile 2/4 again"}, out);
  expect_merge_refused({t1, t2, dir + "/two/2.qtmt", t4}, options, {dir + "/two/2.qtmt", "one split"}, out);
  expect_merge_refused({dir + "/four/9.qtmt"}, options, {dir + "/four/9.qtmt", "no such file"}, out);
  expect_merge_refused({kCentres}, options, {kCentres, "not a qtmvoronoi tile product"}, out);
  fs::create_directories(dir + "/empty");
  expect_merge_refused({dir + "/empty"}, options, {dir + "/empty", "without .qtmt"}, out);

  // Another level, rule or set of sites than the merge's.
  VoronoiOptions other = options;
  other.level = 7;
  run_tiles(kCentres, other, 4, dir + "/level7", {3});
  expect_merge_refused({t1, t2, dir + "/level7/3.qtmt", t4}, options, {dir + "/level7/3.qtmt", "level 7"}, out);
  other = options;
  other.rule = label::Rule::cell;
  run_tiles(kCentres, other, 4, dir + "/cell", {3});
  expect_merge_refused({t1, t2, dir + "/cell/3.qtmt", t4}, options, {dir + "/cell/3.qtmt", "-distance cell"}, out);
  other = options;
  other.read.where = "lon > 0";
  run_tiles(kCentres, other, 4, dir + "/east", {3});
  expect_merge_refused({t1, t2, dir + "/east/3.qtmt", t4}, options, {dir + "/east/3.qtmt", "other sites"}, out);

  // Damaged files: one byte changed, cut short, one byte too many.
  const auto damaged = [&](const std::string& name, auto&& change) {
    const std::string path = dir + "/" + name + ".qtmt";
    fs::copy_file(t3, path, fs::copy_options::overwrite_existing);
    std::string bytes = files_of(dir + "/four").at("3.qtmt");
    change(bytes);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return path;
  };
  const std::string flipped = damaged("flipped", [](std::string& b) { b[b.size() / 2] ^= 0x10; });
  expect_merge_refused({t1, t2, flipped, t4}, options, {flipped, "checksum"}, out);
  // Two damaged tiles, read on several threads: the error names the first in code order.
  const std::string flipped2 = dir + "/flipped2.qtmt";
  {
    std::string bytes = files_of(dir + "/four").at("2.qtmt");
    bytes[bytes.size() / 2] ^= 0x10;
    std::ofstream(flipped2, std::ios::binary | std::ios::trunc) << bytes;
  }
  for (int k = 0; k < 4; ++k) expect_merge_refused({t1, flipped2, flipped, t4}, options, {flipped2, "checksum"}, out);
  const std::string cut = damaged("cut", [](std::string& b) { b.resize(b.size() - 100); });
  expect_merge_refused({t1, t2, cut, t4}, options, {cut, "truncated"}, out);
  const std::string longer = damaged("longer", [](std::string& b) { b.push_back('x'); });
  expect_merge_refused({t1, t2, longer, t4}, options, {longer, "too many"}, out);
  const std::string header = damaged("header", [](std::string& b) { b[20] = 9; });  // the tile index
  expect_merge_refused({t1, t2, header, t4}, options, {header, "corrupt"}, out);

  // The good ones still merge; a raster destination is refused before any work.
  VoronoiOptions merge = options;
  merge.merge = {dir + "/four"};
  EXPECT_NO_THROW(run_voronoi(kCentres, out, merge));
  merge.format.clear();
  merge.kind = OutputKind::automatic;
  EXPECT_THROW(run_voronoi(kCentres, dir + "/out.tif", merge), VoronoiError);
  EXPECT_FALSE(fs::exists(dir + "/out.tif"));
}

// A tile job refuses what a tile cannot be, and writes nothing when stopped.
TEST(TileMerge, TileJobsRefuseBadTilesAndStopCleanly) {
  const std::string dir = test::test_dir();
  VoronoiOptions options = case_options(kCentres, 3);
  options.tile_index = 1;
  options.tile_count = 33;  // level 3 splits into at most 32
  try {
    run_voronoi(kCentres, dir + "/t.qtmt", options);
    ADD_FAILURE() << "33 tiles at level 3 accepted";
  } catch (const VoronoiError& e) {
    EXPECT_NE(std::string(e.what()).find("-tile: level 3 splits into 1 to 32 tiles"), std::string::npos) << e.what();
  }
  options.tile_count = 4;
  options.progress = [](double f, const char*) { return f < 0.5; };
  EXPECT_THROW(run_voronoi(kCentres, dir + "/t.qtmt", options), Interrupted);
  EXPECT_FALSE(fs::exists(dir + "/t.qtmt"));
  EXPECT_TRUE(test::hidden_entries(dir).empty());

  // A merge stopped while its tile products are read (on several threads) writes nothing.
  VoronoiOptions merge = case_options(kCentres, 6);
  run_tiles(kCentres, merge, 8, dir + "/eight");
  merge.merge = {dir + "/eight"};
  int reports = 0;  // the merge's: the first (always made, whatever the threads) stops it
  merge.progress = [&reports](double, const char* what) { return std::string(what) != "merge" || ++reports > 1; };
  EXPECT_THROW(run_voronoi(kCentres, dir + "/out", merge), Interrupted);
  EXPECT_EQ(reports, 1);
  EXPECT_FALSE(fs::exists(dir + "/out"));
  EXPECT_TRUE(test::hidden_entries(dir).empty());
}

// The command line: -tile takes K/N and no output options; -merge and -tile exclude each other.
TEST(TileMerge, CommandLineRefusesBadTileOptions) {
  const std::string dir = test::test_dir();
  const std::vector<std::string> csv = {"-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat"};
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::vector<Case> cases = {
      {{"-tile", "3"}, "-tile: '3' is not K/N"},
      {{"-tile", "9/8"}, "K from 1 to N"},
      {{"-tile", "0/8"}, "K from 1 to N"},
      {{"-tile", "1/8", "-layers", "regions"}, "give -layers to the -merge run"},
      {{"-tile", "1/8", "-merge", dir}, "-tile and -merge exclude each other"},
  };
  for (const Case& c : cases) {
    const test::ProcessResult r =
        test::run_qtmvoronoi(test::concat(test::concat(c.args, csv), {kCentres, dir + "/t.qtmt"}));
    EXPECT_EQ(r.status, 2) << c.says;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/t.qtmt"));
  }
}

}  // namespace
}  // namespace qtmv
