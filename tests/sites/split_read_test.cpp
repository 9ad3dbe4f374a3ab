// The split read (split_read.hpp): a CSV read by several GDAL datasets at once, each a range of
// its lines, gives the sequential read's sites, pieces, covers, FIDs, attributes, summary and
// messages with 2 and 8 threads; sources it cannot prove the same for are read on one thread
// (the read trace says why), with the same results.
#include <gtest/gtest.h>

#include <cpl_conv.h>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/trace.hpp"
#include "read_comparison.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::Read;
using test::temp_path;

/// Sets an environment variable (a run switch) for its lifetime.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) { setenv(name, value.c_str(), 1); }
  ~ScopedEnv() { unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
};

void write_file(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr) << path;
  std::fwrite(text.data(), 1, text.size(), f);
  std::fclose(f);
}

/// Reads `path` on one thread, then with 2, 8 and 16 threads in ranges of `range_bytes`, and
/// expects the same of each; `split`: the read trace says the reads of several threads were split,
/// by no more than 8 of them (else that they were read on one thread, saying `why`). Returns the
/// one thread's read.
Read same_as_sequential(const std::string& path, const ReadOptions& options, std::size_t range_bytes, bool split,
                        const std::string& why = "") {
  const ScopedEnv trace("QTMV_TRACE", "read");
  const ScopedEnv ranges("QTMV_READ_RANGE_BYTES", std::to_string(range_bytes));
  std::vector<std::string> traced;
  const ScopedTraceSink sink([&traced](Severity, const std::string& line) { traced.push_back(line); });
  Read one = test::read_with(path, options, 1);
  EXPECT_TRUE(test::any_contains(traced, "read on one thread: the run has one thread"));
  for (const int threads : {2, 8, 16}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    traced.clear();
    test::expect_same(one, test::read_with(path, options, threads));
    EXPECT_EQ(test::any_contains(traced, ": split read: "), split) << (traced.empty() ? "" : traced.front());
    for (const std::string& line : traced) {
      const std::size_t by = line.find(", read by ");
      if (by != std::string::npos) {
        EXPECT_LE(std::stoi(line.substr(by + 10)), std::min(threads, 8)) << line;
      }
    }
    if (!split) {
      EXPECT_TRUE(test::any_contains(traced, why)) << (traced.empty() ? "" : traced.front());
    }
  }
  return one;
}

ReadOptions lonlat_options(int level) {
  ReadOptions o = test::options_at(level, nullptr);
  o.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  return o;
}

/// `n` seeded points "id,lon,lat,name" with `newline` after each line.
std::string points_text(int n, const char* newline, unsigned seed) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::string text = std::string("id,lon,lat,name") + newline;
  char line[128];
  for (int k = 0; k < n; ++k) {
    std::snprintf(line, sizeof line, "%d,%.7f,%.7f,p%d%s", k, 180.0 * uniform(random), 89.0 * uniform(random), k,
                  newline);
    text += line;
  }
  return text;
}

TEST(SplitRead, ManyRangesOfPointsAreTheSequentialRead) {
  const std::string path = temp_path("points.csv");
  write_file(path, points_text(120000, "\n", 1));
  const Read read = same_as_sequential(path, lonlat_options(10), 64 << 10, true);  // about 70 ranges
  EXPECT_EQ(read.set.summary.sites, 120000u);
  EXPECT_EQ(read.set.table.sites.back().fid, 120000);
  ReadOptions where = lonlat_options(10);
  where.where = "name LIKE 'p1%' OR id = '77'";
  EXPECT_EQ(same_as_sequential(path, where, 64 << 10, true).set.summary.sites, 1u + 10 + 100 + 1000 + 10000 + 20000 + 1);
  where.where = "FID > 100";  // each part numbers its own FIDs
  same_as_sequential(path, where, 64 << 10, false, "-where names an FID");
}

// A range may start or end at a blank line (skipped by GDAL without an FID), a CRLF, a line of
// spaces (a feature without geometry), the last line has no line feed; the .csvt makes id an
// Integer, whose bad values GDAL warns of once a layer with the record's number; the .prj
// gives the CRS.
TEST(SplitRead, LineEndsBlankLinesAndSidecarsAreTheSequentialRead) {
  const std::string path = temp_path("mixed.csv");
  std::string text = points_text(1500, "\r\n", 2);
  for (std::size_t at = 40, k = 0; at < text.size(); at += 397, ++k) {
    at = text.find('\n', at) + 1;
    if (at == 0) break;
    const char* insert[] = {"\n", "\r\n", "\r\n\r\n", "   \r\n", "x,1,2,bad id\n", "\n\n"};
    text.insert(at, insert[k % 6]);
  }
  text.erase(text.size() - 2);  // no line feed at the end
  write_file(path, text);
  write_file(path.substr(0, path.size() - 3) + "csvt", "Integer,Real,Real,String\n");
  write_file(path.substr(0, path.size() - 3) + "prj", "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]]");
  for (const std::size_t range : {std::size_t{1}, std::size_t{700}}) {
    SCOPED_TRACE("ranges of " + std::to_string(range) + " bytes");
    const Read read = same_as_sequential(path, lonlat_options(9), range, true);
    EXPECT_GT(read.set.summary.skipped_empty, 10u);
    EXPECT_EQ(read.set.table.definition()->GetFieldDefn(0)->GetType(), OFTInteger);
    EXPECT_TRUE(test::any_contains(read.messages, "Invalid value type found in record"));
  }
}

TEST(SplitRead, WhatItCannotProveTheSameIsReadOnOneThread) {
  const ReadOptions o = lonlat_options(8);
  // WKT geometries are quoted: a quoted field may hold a line break.
  const std::string wkt = temp_path("lines.csv");
  std::string text = "WKT,name\n";
  for (int k = 0; k < 2000; ++k) {
    text += "\"LINESTRING (" + std::to_string(k % 360 - 180) + " 10," + std::to_string(k % 360 - 179) + " 11)\",l" +
            std::to_string(k) + "\n";
  }
  write_file(wkt, text);
  same_as_sequential(wkt, test::options_at(8, nullptr), 512, false, "a quote in the data");
  // One quote somewhere.
  const std::string quoted = temp_path("quoted.csv");
  text = points_text(2000, "\n", 3);
  text.insert(text.find(",p1500\n") + 1, "\"p\"");
  write_file(quoted, text);
  same_as_sequential(quoted, o, 512, false, "a quote in the data");
  // No header line: the first line is data.
  const std::string headless = temp_path("headless.csv");
  text = points_text(2000, "\n", 4);
  write_file(headless, text.substr(text.find('\n') + 1));
  ReadOptions fields = test::options_at(8, nullptr);
  fields.open_options = {"X_POSSIBLE_NAMES=field_2", "Y_POSSIBLE_NAMES=field_3"};
  same_as_sequential(headless, fields, 512, false, "the first line is data");
  // Types guessed from the file's first lines.
  const std::string points = temp_path("points.csv");
  write_file(points, points_text(2000, "\n", 5));
  ReadOptions guessed = o;
  guessed.open_options.push_back("AUTODETECT_TYPE=YES");
  same_as_sequential(points, guessed, 512, false, "-oo AUTODETECT_TYPE=YES");
  // A lone carriage return.
  const std::string cr = temp_path("cr.csv");
  text = points_text(2000, "\n", 6);
  text[text.find("\n", 5000)] = '\r';
  write_file(cr, text);
  same_as_sequential(cr, o, 512, false, "a carriage return not before a line feed");
  // -sql.
  ReadOptions sql = o;
  sql.sql = std::string("SELECT * FROM \"") + CPLGetBasename(points.c_str()) + "\" WHERE id <> '5'";
  same_as_sequential(points, sql, 512, false, "-sql");
  // A header-only file.
  const std::string empty = temp_path("empty.csv");
  write_file(empty, "id,lon,lat\n");
  EXPECT_THROW(test::read_with(empty, o, 2), ReadError);
}


// A line longer than -oo MAX_LINE_SIZE: GDAL's read fails there and ends, sequential or split
// (the ranges after it are not handed on); the read fails with the same message.
TEST(SplitRead, AFailedPartEndsTheReadAsTheSequentialReadEnds) {
  const std::string path = temp_path("long_line.csv");
  std::string text = points_text(3000, "\n", 7);
  const std::size_t at = text.find("\n", text.size() / 2) + 1;
  text.insert(at, "1,2,3," + std::string(300, 'x') + "\n");
  write_file(path, text);
  ReadOptions o = lonlat_options(8);
  o.open_options.push_back("MAX_LINE_SIZE=200");
  const ScopedEnv ranges("QTMV_READ_RANGE_BYTES", "2000");
  std::string sequential;
  try {
    test::read_with(path, o, 1);
  } catch (const ReadError& e) {
    sequential = e.what();
  }
  EXPECT_NE(sequential.find("reading failed"), std::string::npos) << sequential;
  for (const int threads : {2, 8}) {
    try {
      test::read_with(path, o, threads);
      ADD_FAILURE() << "no error with " << threads << " threads";
    } catch (const ReadError& e) {
      EXPECT_EQ(e.what(), sequential);
    }
  }
}

// The progress callback's stop ends a split read (its threads stopped and joined) with Interrupted.
TEST(SplitRead, AStopAskedForEndsTheRead) {
  const std::string path = temp_path("points.csv");
  write_file(path, points_text(60000, "\n", 8));
  const ScopedEnv ranges("QTMV_READ_RANGE_BYTES", "20000");
  ReadOptions o = lonlat_options(8);
  int calls = 0;
  double last = 0.0;
  o.progress = [&](double done, const std::string&) {
    last = done;
    return ++calls < 50;
  };
  EXPECT_THROW(test::read_with(path, o, 4), Interrupted);
  EXPECT_EQ(calls, 50);
  EXPECT_GT(last, 0.0);  // the ranges handed on
  EXPECT_LT(last, 1.0);
}

/// A GeoPackage layer "points" of `n` seeded points with a name, every 1000th FID deleted.
std::string points_gpkg(int n) {
  const std::string path = temp_path("points.gpkg");
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GPKG")->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  OGRSpatialReference wgs84 = test::srs_of("EPSG:4326");
  OGRLayer* layer = ds->CreateLayer("points", &wgs84, wkbPoint, nullptr);
  OGRFieldDefn field("name", OFTString);
  layer->CreateField(&field);
  std::mt19937_64 random(9);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  ds->StartTransaction();
  for (int k = 0; k < n; ++k) {
    OGRFeatureUniquePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    feature->SetField("name", ("g" + std::to_string(k)).c_str());
    feature->SetGeometryDirectly(new OGRPoint(180.0 * uniform(random), 89.0 * uniform(random)));
    if (layer->CreateFeature(feature.get()) != OGRERR_NONE) throw std::runtime_error("cannot write " + path);
  }
  for (GIntBig fid = 1000; fid <= n; fid += 1000) {
    if (layer->DeleteFeature(fid) != OGRERR_NONE) throw std::runtime_error("cannot delete from " + path);
  }
  ds->CommitTransaction();
  return path;
}

// A GeoPackage table is read in FID ranges, each on its own connection, in rowid order as its
// whole read is; a feature GDAL cannot decode is skipped with GDAL's message at its place.
TEST(SplitRead, AGeoPackageInFidRangesIsTheSequentialRead) {
  const std::string path = points_gpkg(40000);
  test::corrupt_geometry(path, 31234);
  const Read read = same_as_sequential(path, test::options_at(9, nullptr), 0, true);
  EXPECT_EQ(read.set.summary.features, 40000u - 40);
  EXPECT_EQ(read.set.summary.skipped_unreadable, 1u);
  EXPECT_EQ(read.set.table.sites.back().fid, 39999);
  ReadOptions where = test::options_at(9, nullptr);
  where.where = "name LIKE 'g1%'";
  same_as_sequential(path, where, 0, false, "-where (SQLite may read it in an index's order)");
}

}  // namespace
}  // namespace qtmv::sites
