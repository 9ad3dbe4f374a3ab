// Raster parts (-tile K/N -part PART.tif, then -merge PARTS -of VRT index.vrt): each part is its
// band of the whole raster's rows (lon/lat: floor((K-1) H / N) to floor(K H / N); QTM-coded: the
// rows of tile K's cells) with its geotransform offset to its first row, and the index read
// through GDAL is the whole run's raster pixel for pixel (boundary band on the parts' edge rows
// and distance band included), with its grid, bands, type, nodata and metadata; every bad set of
// parts is refused naming the file, writing nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gdal_priv.h>

#include "parts_test_support.hpp"
#include "qtmvoronoi_test_support.hpp"
#include "voronoi.hpp"
#include "write/raster_bands.hpp"

namespace qtmv {
namespace {

namespace fs = std::filesystem;
using test::expect_index_refused;
using test::run_index;

const std::string kCentres = std::string(QTMV_TESTDATA_DIR) + "/country_centres.csv";

VoronoiOptions raster_options(int level, write::RasterGrid::Layout layout, const std::string& bands,
                              const std::string& type) {
  VoronoiOptions o;
  o.level = level;
  o.device = "cpu";
  o.kind = OutputKind::raster;
  o.raster.layout = layout;
  if (!bands.empty()) o.raster.bands = write::parse_raster_bands(bands);
  o.raster.data_type = type;
  o.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  o.read.source_srs = "EPSG:4326";
  return o;
}

/// Tile jobs k = 1..n (those of `which`, all when empty) writing parts dir/k.tif.
void run_parts(const VoronoiOptions& options, int n, const std::string& dir, const std::vector<int>& which = {}) {
  test::run_parts(kCentres, options, n, dir, "tif", which);
}

/// Every band's pixels of `path`, in its own data type's bytes, band after band.
std::vector<unsigned char> pixels_of(GDALDataset& ds) {
  std::vector<unsigned char> out;
  for (int b = 1; b <= ds.GetRasterCount(); ++b) {
    GDALRasterBand* band = ds.GetRasterBand(b);
    const GDALDataType type = band->GetRasterDataType();
    const std::size_t bytes = static_cast<std::size_t>(ds.GetRasterXSize()) * ds.GetRasterYSize() *
                              GDALGetDataTypeSizeBytes(type);
    const std::size_t at = out.size();
    out.resize(at + bytes);
    EXPECT_EQ(band->RasterIO(GF_Read, 0, 0, ds.GetRasterXSize(), ds.GetRasterYSize(), out.data() + at,
                             ds.GetRasterXSize(), ds.GetRasterYSize(), type, 0, 0, nullptr),
              CE_None);
  }
  return out;
}

/// The index of n parts equals the whole raster: size, georeferencing, bands (type, nodata,
/// description, unit), metadata and pixels; each part is its rows, with its geotransform.
void expect_index_is_whole(const VoronoiOptions& options, int n, const std::string& dir) {
  SCOPED_TRACE(std::to_string(n) + " tiles in " + dir);
  const std::string whole = dir + "/whole.tif", index = dir + "/index" + std::to_string(n) + ".vrt";
  fs::create_directories(dir);
  if (!fs::exists(whole)) run_voronoi(kCentres, whole, options);
  run_parts(options, n, dir + "/parts" + std::to_string(n));
  run_index({dir + "/parts" + std::to_string(n)}, index);
  const GDALDatasetUniquePtr a = test::open_dataset(whole, GDAL_OF_RASTER);
  const GDALDatasetUniquePtr b = test::open_dataset(index, GDAL_OF_RASTER);
  ASSERT_TRUE(a && b);
  ASSERT_EQ(a->GetRasterXSize(), b->GetRasterXSize());
  ASSERT_EQ(a->GetRasterYSize(), b->GetRasterYSize());
  ASSERT_EQ(a->GetRasterCount(), b->GetRasterCount());
  const bool lonlat = options.raster.layout == write::RasterGrid::Layout::lonlat;
  double ta[6], tb[6];
  EXPECT_EQ(a->GetGeoTransform(ta) == CE_None, lonlat);
  EXPECT_EQ(b->GetGeoTransform(tb) == CE_None, lonlat);
  if (lonlat) {
    for (int k = 0; k < 6; ++k) EXPECT_EQ(ta[k], tb[k]) << k;
    ASSERT_TRUE(b->GetSpatialRef());
    EXPECT_TRUE(a->GetSpatialRef()->IsSame(b->GetSpatialRef()));
  }
  for (const char* item : {"QTM_LEVEL", "QTM_LAYOUT"}) {
    ASSERT_TRUE(b->GetMetadataItem(item)) << item;
    EXPECT_STREQ(a->GetMetadataItem(item), b->GetMetadataItem(item)) << item;
  }
  for (int k = 1; k <= a->GetRasterCount(); ++k) {
    GDALRasterBand *x = a->GetRasterBand(k), *y = b->GetRasterBand(k);
    EXPECT_EQ(x->GetRasterDataType(), y->GetRasterDataType());
    EXPECT_EQ(x->GetNoDataValue(), y->GetNoDataValue());
    EXPECT_STREQ(x->GetDescription(), y->GetDescription());
    EXPECT_STREQ(x->GetUnitType(), y->GetUnitType());
  }
  EXPECT_TRUE(pixels_of(*a) == pixels_of(*b)) << "the index's pixels differ from the whole raster's";
  // Each part: the whole raster's width, its rows, its geotransform at its first row.
  const int height = a->GetRasterYSize();
  for (int k = 1; k <= n && lonlat; ++k) {
    const GDALDatasetUniquePtr part =
        test::open_dataset(dir + "/parts" + std::to_string(n) + "/" + std::to_string(k) + ".tif", GDAL_OF_RASTER);
    ASSERT_TRUE(part);
    const int first = static_cast<int>(static_cast<long long>(k - 1) * height / n);
    const int end = static_cast<int>(static_cast<long long>(k) * height / n);
    EXPECT_EQ(part->GetRasterXSize(), a->GetRasterXSize());
    EXPECT_EQ(part->GetRasterYSize(), end - first) << "tile " << k;
    double tp[6];
    ASSERT_EQ(part->GetGeoTransform(tp), CE_None);
    EXPECT_EQ(tp[0], ta[0]);
    EXPECT_EQ(tp[1], ta[1]);
    EXPECT_EQ(tp[2], 0.0);
    EXPECT_DOUBLE_EQ(tp[3], ta[3] + first * ta[5]) << "tile " << k;
    EXPECT_EQ(tp[4], 0.0);
    EXPECT_EQ(tp[5], ta[5]);
  }
}

TEST(RasterParts, IndexEqualsTheWholeRasterPixelForPixel) {
  const std::string dir = test::test_dir();
  struct Set {
    const char* name;
    write::RasterGrid::Layout layout;
    const char* bands;
    const char* type;
  };
  const Set sets[] = {{"fid", write::RasterGrid::Layout::lonlat, "fid", ""},
                      {"all", write::RasterGrid::Layout::lonlat, "fid,boundary,distance", ""},
                      {"int16", write::RasterGrid::Layout::lonlat, "fid,boundary", "Int16"},
                      {"qtm", write::RasterGrid::Layout::qtm, "fid,boundary,distance", ""}};
  for (const Set& set : sets) {
    SCOPED_TRACE(set.name);
    const VoronoiOptions options = raster_options(5, set.layout, set.bands, set.type);
    for (const int n : {1, 2, 3, 7}) expect_index_is_whole(options, n, dir + "/" + set.name);
  }
}

TEST(RasterParts, BadPartSetsAreRefusedNamingTheFile) {
  const std::string dir = test::test_dir();
  const VoronoiOptions options = raster_options(5, write::RasterGrid::Layout::lonlat, "fid,boundary", "");
  run_parts(options, 4, dir + "/four");
  const std::string p1 = dir + "/four/1.tif", p2 = dir + "/four/2.tif", p3 = dir + "/four/3.tif",
                    p4 = dir + "/four/4.tif";
  const std::string index = dir + "/index.vrt";
  expect_index_refused({p1, p2, p4}, {"1 of the 4 parts missing (tile 3)"}, index);
  expect_index_refused({dir + "/four", p2}, {p2, "tile 2/4 again"}, index);
  run_parts(options, 2, dir + "/two", {2});
  expect_index_refused({p1, p2, dir + "/two/2.tif", p4}, {dir + "/two/2.tif", "one split"}, index);
  // A whole run's raster is not a part; nor are parts of other bands, type, size or level.
  run_voronoi(kCentres, dir + "/whole.tif", options);
  expect_index_refused({p1, p2, dir + "/whole.tif", p4}, {dir + "/whole.tif", "not a part"}, index);
  VoronoiOptions other = raster_options(5, write::RasterGrid::Layout::lonlat, "fid", "");
  run_parts(other, 4, dir + "/fid", {3});
  expect_index_refused({p1, p2, dir + "/fid/3.tif", p4}, {dir + "/fid/3.tif", "same -bands"}, index);
  other = raster_options(5, write::RasterGrid::Layout::lonlat, "fid,boundary", "Int16");
  run_parts(other, 4, dir + "/int16", {3});
  expect_index_refused({p1, p2, dir + "/int16/3.tif", p4}, {dir + "/int16/3.tif", "same -ot"}, index);
  other = raster_options(5, write::RasterGrid::Layout::lonlat, "fid,boundary", "");
  other.raster.width = 100;
  other.raster.height = 50;
  run_parts(other, 4, dir + "/ts", {3});
  expect_index_refused({p1, p2, dir + "/ts/3.tif", p4}, {dir + "/ts/3.tif", "100 x 50 pixels"}, index);
  other = raster_options(5, write::RasterGrid::Layout::qtm, "fid,boundary", "");
  run_parts(other, 4, dir + "/qtm", {3});
  expect_index_refused({p1, p2, dir + "/qtm/3.tif", p4}, {dir + "/qtm/3.tif", "qtm raster"}, index);
  other = raster_options(6, write::RasterGrid::Layout::lonlat, "fid,boundary", "");
  run_parts(other, 4, dir + "/level6", {3});
  expect_index_refused({p1, p2, dir + "/level6/3.tif", p4}, {dir + "/level6/3.tif", "level 6"}, index);
  // Raster and vector parts are not one output, whichever comes first.
  VoronoiOptions vector = other;
  vector.level = 5;
  vector.kind = OutputKind::vector;
  vector.raster = write::RasterGrid();
  vector.vector.layers = {"regions"};
  vector.part = true;
  vector.tile_index = 3;
  vector.tile_count = 4;
  run_voronoi(kCentres, dir + "/3.gpkg", vector);
  expect_index_refused({p1, p2, dir + "/3.gpkg", p4}, {dir + "/3.gpkg", "a vector part", "all raster or all vector"},
                       index);
  expect_index_refused({dir + "/3.gpkg", p1}, {p1, "a raster part", "all raster or all vector"}, index);
  // The good ones index; relative paths: the index moved with its parts still opens.
  EXPECT_NO_THROW(run_index({dir + "/four"}, index));
  fs::create_directories(dir + "/moved");
  fs::rename(dir + "/four", dir + "/moved/four");
  fs::rename(index, dir + "/moved/index.vrt");
  const GDALDatasetUniquePtr moved = test::open_dataset(dir + "/moved/index.vrt", GDAL_OF_RASTER);
  const GDALDatasetUniquePtr whole = test::open_dataset(dir + "/whole.tif", GDAL_OF_RASTER);
  ASSERT_TRUE(moved && whole);
  EXPECT_TRUE(pixels_of(*moved) == pixels_of(*whole));
}

// The command line: a raster part takes the raster's options; more tiles than rows are refused.
TEST(RasterParts, CommandLine) {
  const std::string dir = test::test_dir();
  const std::vector<std::string> csv = {"-q", "-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-level", "5"};
  test::ProcessResult r = test::run_qtmvoronoi(test::concat(
      csv, {"-tile", "2/2", "-part", "-raster", "lonlat", "-ot", "Int32", "-bands", "fid", kCentres, dir + "/2.tif"}));
  ASSERT_EQ(r.status, 0) << r.err;
  r = test::run_qtmvoronoi(test::concat(
      csv, {"-tile", "1/2", "-part", "-raster", "lonlat", "-ot", "Int32", "-bands", "fid", kCentres, dir + "/1.tif"}));
  ASSERT_EQ(r.status, 0) << r.err;
  r = test::run_qtmvoronoi({"-q", "-merge", dir + "/1.tif", "-merge", dir + "/2.tif", dir + "/index.vrt"});
  ASSERT_EQ(r.status, 0) << r.err;
  const GDALDatasetUniquePtr ds = test::open_dataset(dir + "/index.vrt", GDAL_OF_RASTER);
  ASSERT_TRUE(ds);
  EXPECT_EQ(ds->GetRasterCount(), 1);
  EXPECT_EQ(ds->GetRasterBand(1)->GetRasterDataType(), GDT_Int32);
  // 40 tiles of a raster of 32 rows; -ot for a vector part.
  r = test::run_qtmvoronoi(
      test::concat(csv, {"-tile", "1/40", "-part", "-ts", "64", "32", kCentres, dir + "/many.tif"}));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("fewer than the 40 tiles"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/many.tif"));
  r = test::run_qtmvoronoi(test::concat(csv, {"-tile", "1/2", "-part", "-ot", "Int32", kCentres, dir + "/p.gpkg"}));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("-ot is for raster output"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/p.gpkg"));
}

}  // namespace
}  // namespace qtmv
