// A layer's feature count for the progress: at once where the driver knows it cheaply (a
// GeoPackage), with one thread, and for -sql; a CSV's beside the reading on a handle of its own
// (none with -where, as GDAL would read it through); the progress asked every 256 features, its
// fractions rising to 1, a stop heard at once.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include <cpl_conv.h>

#include "sites/feature_count.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::options_at;
using test::temp_path;

std::string csv_of(int rows) {
  const std::string path = temp_path("rows.csv");
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs("lon,lat,name\n", f);
  for (int k = 0; k < rows; ++k) std::fprintf(f, "%d,%d,n%d\n", k % 360 - 180, k % 180 - 90, k % 7);
  std::fclose(f);
  return path;
}

GIntBig count_of(const std::string& path, const ReadOptions& options, int threads, bool* at_once = nullptr) {
  GDALAllRegister();
  gdal::ErrorCapture errors;
  const OgrSource source = open_source(path, options, errors);
  if (!options.where.empty()) source.layers[0].layer->SetAttributeFilter(options.where.c_str());
  FeatureCount count(source, 0, options, threads);
  if (at_once) *at_once = count.get() >= 0;
  return count.wait();
}

TEST(FeatureCount, CountedAtOnceOrBesideTheReading) {
  const std::string csv = csv_of(5000);
  ReadOptions o = options_at(4, nullptr);
  o.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  bool at_once = false;
  EXPECT_EQ(count_of(csv, o, 1, &at_once), 5000);
  EXPECT_TRUE(at_once);
  EXPECT_EQ(count_of(csv, o, 4), 5000);
  o.where = "name = 'n3'";  // GDAL counts it only by reading it (as before: no fraction)
  EXPECT_EQ(count_of(csv, o, 4), -1);
  EXPECT_EQ(count_of(csv, o, 1), -1);
  o.where.clear();
  o.sql = "SELECT * FROM \"" + std::string(CPLGetBasename(csv.c_str())) + "\"";
  EXPECT_EQ(count_of(csv, o, 4, &at_once), 5000);
  EXPECT_TRUE(at_once);
  std::vector<test::TestFeature> features(300, {"POINT (1 2)", "x"});
  const std::string gpkg = test::make_dataset(temp_path("fast.gpkg"), "GPKG", "fast", "EPSG:4326", features);
  EXPECT_EQ(count_of(gpkg, options_at(4, nullptr), 4, &at_once), 300);
  EXPECT_TRUE(at_once);
}

TEST(FeatureCount, ProgressRisesToTheEndAndAStopIsHeardBeforeTheCount) {
  const std::string csv = csv_of(200000);
  for (const int threads : {1, 2}) {
    ReadOptions o = options_at(4, nullptr);
    o.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
    o.threads = threads;
    std::vector<double> fractions;
    o.progress = [&](double f, const char*) {
      fractions.push_back(f);
      return true;
    };
    read_sites(csv, o);
    EXPECT_GT(fractions.size(), 200000u / 256);
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    EXPECT_GT(fractions[fractions.size() - 2], 0.9);  // the count came before the end
    EXPECT_EQ(fractions.back(), 1.0);
    int calls = 0;
    o.progress = [&](double, const char*) { return ++calls < 3; };  // a stop at the third call
    EXPECT_THROW(read_sites(csv, o), Interrupted);
    EXPECT_EQ(calls, 3);
  }
}

TEST(FeatureCount, GuessedBeforeTheReadFromACountOrACsvsBytes) {
  GDALAllRegister();
  SourceOptions o;
  o.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  // A CSV's rows from its size and first rows: rows of 12 to 17 bytes, within 2%.
  for (const int rows : {3, 5000, 200000}) {
    const std::string csv = csv_of(rows);
    const auto guess = static_cast<double>(feature_count_guess(csv, o));
    EXPECT_NEAR(guess, rows, 0.02 * rows + 1) << rows << " rows";
  }
  const std::string csv = csv_of(5000);
  o.layers = {CPLGetBasename(csv.c_str())};
  EXPECT_NEAR(static_cast<double>(feature_count_guess(csv, o)), 5000, 100);
  o.layers = {"no_such_layer"};
  EXPECT_EQ(feature_count_guess(csv, o), 0u);
  o.layers.clear();
  // A filter's share is not known before the read: no guess.
  o.where = "name = 'n3'";
  EXPECT_EQ(feature_count_guess(csv, o), 0u);
  o.where.clear();
  o.sql = "SELECT * FROM \"" + std::string(CPLGetBasename(csv.c_str())) + "\"";
  EXPECT_EQ(feature_count_guess(csv, o), 0u);
  o.sql.clear();
  EXPECT_EQ(feature_count_guess(csv_of(0), o), 0u);  // a header alone
  EXPECT_EQ(feature_count_guess(temp_path("missing.csv"), o), 0u);
  // A GeoPackage's count, exactly.
  std::vector<test::TestFeature> features(300, {"POINT (1 2)", "x"});
  const std::string gpkg = test::make_dataset(temp_path("guess.gpkg"), "GPKG", "guess", "EPSG:4326", features);
  EXPECT_EQ(feature_count_guess(gpkg, SourceOptions()), 300u);
}

}  // namespace
}  // namespace qtmv::sites
