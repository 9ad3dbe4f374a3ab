// The reader on all threads (issue 37): GDAL reads the features on one thread while the others
// examine, build and append those read before. With 1, 2 and 8 threads the reader gives the same
// sites, pieces, site cells, covers (fixed cells and nodes), site table, summary and messages,
// for points, lines and polygons: the test data, and sources made here that run through several
// chunks (65 536 features) and hold what the reader reports (skipped features, invalid
// polygons, failed transformations, features joined across +-180).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <ogr_srs_api.h>

#include "sites/ogr_site_reader.hpp"
#include "read_comparison.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::options_at;
using test::Read;
using test::read_with;
using test::same_with_any_threads;
using test::temp_path;

const std::string kCountries = std::string(QTMV_TESTDATA_DIR) + "/world_atlas_countries_110m.gpkg";
const std::string kCentres = std::string(QTMV_TESTDATA_DIR) + "/country_centres.csv";

std::FILE* open_for_writing(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  return f;
}

/// `n` points spread over the sphere (seeded), every 9973rd without latitude ("nan") and every
/// 10007th beyond +-90.
std::string points_csv(int n) {
  const std::string path = temp_path("points.csv");
  std::FILE* f = open_for_writing(path);
  std::mt19937_64 random(37);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::fputs("lon,lat,name\n", f);
  for (int k = 0; k < n; ++k) {
    const double lon = 180.0 * uniform(random), lat = std::asin(uniform(random)) * 180.0 / M_PI;
    if (k % 9973 == 17) {
      std::fprintf(f, "%.7f,nan,p%d\n", lon, k);
    } else {
      std::fprintf(f, "%.7f,%.7f,p%d\n", lon, k % 10007 == 5 ? 91.0 : lat, k);
    }
  }
  std::fclose(f);
  return path;
}

/// `n` lines of 2 to 12 vertices wandering half a degree a step, some across +-180.
std::string lines_csv(int n) {
  const std::string path = temp_path("lines.csv");
  std::FILE* f = open_for_writing(path);
  std::mt19937_64 random(38);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::fputs("WKT,name\n", f);
  for (int k = 0; k < n; ++k) {
    double lon = 180.0 * uniform(random), lat = 80.0 * uniform(random);
    const int vertices = 2 + static_cast<int>(random() % 11);
    std::fputs("\"LINESTRING (", f);
    for (int v = 0; v < vertices; ++v) {
      std::fprintf(f, "%s%.6f %.6f", v ? "," : "", lon, lat);
      lon += 0.5 * uniform(random);
      lat = std::max(-89.0, std::min(89.0, lat + 0.5 * uniform(random)));
      if (lon > 180.0) lon -= 360.0;  // written across +-180: joined the short way
      if (lon < -180.0) lon += 360.0;
    }
    std::fprintf(f, ")\",l%d\n", k);
  }
  std::fclose(f);
  return path;
}

/// `n` polygons of 3 to 40 vertices and 0.2 to 6 degrees (every 50th 25), every 97th a bow-tie
/// (invalid), every 131st a collection with a point beyond +-90.
std::string polygons_csv(int n) {
  const std::string path = temp_path("polygons.csv");
  std::FILE* f = open_for_writing(path);
  std::mt19937_64 random(39);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::fputs("WKT,name\n", f);
  for (int k = 0; k < n; ++k) {
    const double lon = -180.0 + 360.0 * unit(random), lat = -75.0 + 150.0 * unit(random);
    const double size = 0.2 + (k % 50 ? 5.8 : 24.8) * unit(random);
    std::string ring;
    const auto vertex = [&ring](double x, double y) {
      char text[64];
      std::snprintf(text, sizeof text, "%s%.6f %.6f", ring.empty() ? "" : ",", x, y);
      ring += text;
    };
    if (k % 97 == 3) {
      for (const auto& [x, y] : {std::pair{0.0, 0.0}, {1.0, 1.0}, {1.0, 0.0}, {0.0, 1.0}, {0.0, 0.0}}) {
        vertex(lon + size * x, lat + size * y);
      }
    } else {
      const int vertices = 3 + static_cast<int>(random() % 38);
      double x0 = 0, y0 = 0;
      for (int v = 0; v < vertices; ++v) {
        const double a = 2.0 * M_PI * v / vertices, r = size * (0.6 + 0.4 * unit(random));
        vertex(lon + r * std::cos(a), lat + 0.5 * size * std::sin(a));
        if (v == 0) x0 = lon + r, y0 = lat;
      }
      vertex(x0, y0);
    }
    if (k % 131 == 5) {
      std::fprintf(f, "\"GEOMETRYCOLLECTION (POLYGON ((%s)),POINT (%.6f 95))\",g%d\n", ring.c_str(), lon, k);
    } else {
      std::fprintf(f, "\"POLYGON ((%s))\",g%d\n", ring.c_str(), k);
    }
  }
  std::fclose(f);
  return path;
}

/// `n` points and small squares in an orthographic projection's plane, about a quarter of them
/// outside its disc (their transformation to lon/lat fails).
std::string orthographic_csv(int n) {
  const std::string path = temp_path("orthographic.csv");
  std::FILE* f = open_for_writing(path);
  std::mt19937_64 random(40);
  std::uniform_real_distribution<double> uniform(-6.6e6, 6.6e6);
  std::fputs("WKT,name\n", f);
  for (int k = 0; k < n; ++k) {
    const double x = uniform(random), y = uniform(random);
    if (k % 3) {
      std::fprintf(f, "\"POINT (%.3f %.3f)\",o%d\n", x, y, k);
    } else {
      std::fprintf(f, "\"POLYGON ((%.3f %.3f,%.3f %.3f,%.3f %.3f,%.3f %.3f))\",o%d\n", x, y, x + 2e5, y, x + 2e5,
                   y + 2e5, x, y, k);
    }
  }
  std::fclose(f);
  return path;
}

TEST(LayerReader, PointsAreTheSameWithAnyThreads) {
  ReadOptions o = options_at(10, nullptr);
  o.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  const Read many = same_with_any_threads(points_csv(150000), o);  // three chunks
  EXPECT_EQ(many.set.summary.features, 150000u);
  EXPECT_EQ(many.set.summary.skipped, 16u + 15u);  // no coordinate (a CSV's "nan"), beyond +-90
  EXPECT_EQ(many.set.summary.skipped_coordinate, 15u);
  EXPECT_EQ(many.set.geometry.pieces.size(), many.set.summary.sites);
  o.level = 14;
  same_with_any_threads(kCentres, o);
}

TEST(LayerReader, LinesAreTheSameWithAnyThreads) {
  const Read lines = same_with_any_threads(lines_csv(70000), options_at(8, nullptr));  // two chunks
  EXPECT_EQ(lines.set.summary.sites, 70000u);
  EXPECT_GT(lines.set.summary.wrapped_features, 100u);
  ReadOptions borders = options_at(10, nullptr);
  borders.sql = "SELECT ST_Boundary(geom) AS geom, name FROM countries_110m";
  same_with_any_threads(kCountries, borders);
}

TEST(LayerReader, PolygonsAreTheSameWithAnyThreads) {
  const std::string path = polygons_csv(3000);
  const Read polygons = same_with_any_threads(path, options_at(9, nullptr));
  EXPECT_EQ(polygons.set.summary.invalid_polygons, 31u);
  EXPECT_EQ(polygons.set.summary.skipped_coordinate, 23u);
  EXPECT_GT(polygons.set.geometry.fixed_nodes.size(), 0u);
  ReadOptions repaired = options_at(9, nullptr);
  repaired.make_valid = true;
  EXPECT_EQ(same_with_any_threads(path, repaired).set.summary.repaired_polygons, 31u);
  ReadOptions countries = options_at(9, nullptr);
  countries.layers = {"countries_110m"};
  same_with_any_threads(kCountries, countries);
}

// Transformed on all threads, each with its own copy of the transformation; a failure is
// transformed again in feature order with the layer's, whose messages count the failures
// before (the 20th failed point says that further ones are suppressed).
TEST(LayerReader, TransformedFeaturesAndTheirFailuresAreTheSameWithAnyThreads) {
  ReadOptions o = options_at(8, nullptr);
  o.source_srs = "+proj=ortho +lat_0=0 +lon_0=0 +datum=WGS84";
  const Read read = same_with_any_threads(orthographic_csv(70000), o);
  EXPECT_GT(read.set.summary.skipped_transform, 10000u);
  EXPECT_TRUE(test::any_contains(read.messages, "further errors will be suppressed"));
}

}  // namespace
}  // namespace qtmv::sites
