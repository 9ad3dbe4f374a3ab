// The raster writer, read back with GDAL: the QTM-coded raster equals the labels on every cell,
// the lon/lat raster agrees with point location at its pixel centres, and failures are clear.
#include <gtest/gtest.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "../test_temp_dir.hpp"
#include "grid/qtm.hpp"
#include "label/synthetic_sites.hpp"
#include "label/label_session.hpp"
#include "label/labeller.hpp"
#include "common/openmp_threads.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_writer.hpp"

namespace qtmv::write {
namespace {

using grid::Code;

/// Random point sites labelled on the CPU, with FIDs that differ from the site ids.
struct Fixture {
  int level = 0;
  label::LabelResult result;
  sites::SiteTable table;

  Fixture(int level_, int site_count, unsigned seed) : level(level_) {
    label::SiteGeometry g;
    g.level = level;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
    for (int s = 0; s < site_count; ++s) add_point(g, lon(rng), std::asin(z(rng)) * 180.0 / M_PI, s);
    label::LabelOptions options;
    options.device = "cpu";
    result = label::label_all(g.input(), options);
    table.sites.resize(static_cast<std::size_t>(site_count));
    for (int s = 0; s < site_count; ++s) table.sites[s].fid = fid_of(s);
  }
  static std::int64_t fid_of(int site) { return 1000 + 7 * static_cast<std::int64_t>(site); }

  CellLabels labels(bool with_distance = true, bool with_boundary = true) const {
    CellLabels l;
    l.level = level;
    l.site = result.site.data();
    l.distance_m = with_distance ? result.distance_m.data() : nullptr;
    l.boundary = with_boundary ? result.boundary.data() : nullptr;
    return l;
  }
};

// In the process's own directory: two test runs at once (two checkouts) must not share files.
std::string temp_path(const std::string& name) { return qtmv::test::process_temp_dir() + "/raster_" + name; }

/// Opens a raster read-only; closed (and the file removed) when the guard ends.
struct Opened {
  std::string path;
  GDALDatasetH ds = nullptr;
  explicit Opened(std::string p) : path(std::move(p)), ds(GDALOpen(path.c_str(), GA_ReadOnly)) {}
  ~Opened() {
    if (ds) GDALClose(ds);
    VSIUnlink(path.c_str());
  }
};

bool exists(const std::string& path) {
  VSIStatBufL stat;
  return VSIStatL(path.c_str(), &stat) == 0;
}

std::vector<double> read_band(GDALDatasetH ds, int band) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  std::vector<double> values(static_cast<std::size_t>(w) * h);
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, band), GF_Read, 0, 0, w, h, values.data(), w, h, GDT_Float64, 0, 0),
            CE_None);
  return values;
}

double read_pixel(GDALDatasetH ds, int band, int x, int y) {
  double v = 0;
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, band), GF_Read, x, y, 1, 1, &v, 1, 1, GDT_Float64, 0, 0), CE_None);
  return v;
}

std::string metadata(GDALDatasetH ds, const char* key, const char* domain = nullptr) {
  const char* v = GDALGetMetadataItem(ds, key, domain);
  return v ? v : "";
}

class RasterWriter : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { GDALAllRegister(); }
};

/// Every pixel of the QTM-coded raster: its cell's labels, or nodata where j > 2i.
void check_qtm_raster(GDALDatasetH ds, const Fixture& f, bool with_distance) {
  const int L = f.level;
  const int I = 1 << L;
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(GDALGetRasterXSize(ds), 2 * I - 1);
  ASSERT_EQ(GDALGetRasterYSize(ds), 8 * I);
  ASSERT_EQ(GDALGetRasterCount(ds), with_distance ? 3 : 2);
  EXPECT_EQ(metadata(ds, "QTM_LEVEL"), std::to_string(L));
  EXPECT_EQ(metadata(ds, "QTM_LAYOUT"), "octant_row_col");
  EXPECT_EQ(metadata(ds, "QTM_GEOREFERENCED"), "NO");
  double gt[6];
  EXPECT_NE(GDALGetGeoTransform(ds, gt), CE_None) << "the QTM raster must not be georeferenced";
  EXPECT_EQ(GDALGetSpatialRef(ds), nullptr);
  const char* names[3] = {"site_fid", "boundary", "distance_m"};
  for (int b = 1; b <= GDALGetRasterCount(ds); ++b) {
    GDALRasterBandH band = GDALGetRasterBand(ds, b);
    EXPECT_STREQ(GDALGetDescription(band), names[b - 1]);
    int has_nodata = 0;
    EXPECT_EQ(GDALGetRasterNoDataValue(band, &has_nodata), -1.0);
    EXPECT_TRUE(has_nodata);
    // The default types: Float32 with distances (these FIDs are exact in it), else Int32.
    EXPECT_EQ(GDALGetRasterDataType(band), with_distance ? GDT_Float32 : GDT_Int32);
  }
  const std::vector<double> fid = read_band(ds, 1), boundary = read_band(ds, 2);
  const std::vector<double> distance = with_distance ? read_band(ds, 3) : std::vector<double>{};
  const int w = 2 * I - 1;
  std::uint64_t cells = 0;
  int failures = 0;
  for (int y = 0; y < 8 * I && failures < 10; ++y) {
    const int octant = y / I, i = y % I;
    for (int x = 0; x < w && failures < 10; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * w + x;
      if (x > 2 * i) {
        if (fid[p] != -1 || boundary[p] != -1 || (with_distance && distance[p] != -1)) {
          ADD_FAILURE() << "pixel " << x << "," << y << " beyond its row is not nodata";
          ++failures;
        }
        continue;
      }
      ++cells;
      const Code code = grid::code_of({octant, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(x)}, L);
      const std::int32_t site = f.result.site[code];
      bool ok = fid[p] == static_cast<double>(Fixture::fid_of(site)) && boundary[p] == f.result.boundary[code];
      if (with_distance) ok = ok && distance[p] == static_cast<double>(f.result.distance_m[code]);
      if (!ok) {
        ADD_FAILURE() << "level " << L << " cell " << code << " (pixel " << x << "," << y << "): fid " << fid[p]
                      << " boundary " << boundary[p] << " vs site " << site << " boundary "
                      << int(f.result.boundary[code]);
        ++failures;
      }
    }
  }
  if (failures == 0) {
    EXPECT_EQ(cells, grid::cell_count(L));
  }
}

TEST_F(RasterWriter, QtmGeoTiffEqualsLabelsAtLevels2To7) {
  for (int level = 2; level <= 7; ++level) {
    SCOPED_TRACE("level " + std::to_string(level));
    const Fixture f(level, 3 + 5 * level, 100 + level);
    const std::string path = temp_path("qtm_" + std::to_string(level) + ".tif");
    RasterOptions options;
    std::vector<double> fractions;
    options.progress = [&](double fraction, const char*) {
      fractions.push_back(fraction);
      return true;
    };
    write_raster(path, f.labels(), f.table, options);
    Opened opened(path);
    check_qtm_raster(opened.ds, f, true);
    ASSERT_FALSE(fractions.empty());
    EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
    for (std::size_t k = 1; k < fractions.size(); ++k) EXPECT_LE(fractions[k - 1], fractions[k]);
  }
}

TEST_F(RasterWriter, WithoutDistanceOrBoundaryWritesInt32AndComputesBoundaries) {
  const Fixture f(6, 40, 7);
  const std::string path = temp_path("qtm_nodist.tif");
  write_raster(path, f.labels(false, false), f.table, RasterOptions{});
  Opened opened(path);
  check_qtm_raster(opened.ds, f, false);  // boundary compared with the labeller's own
}

TEST_F(RasterWriter, LonLatAgreesWithPointLocationAtPixelCentres) {
  const Fixture f(5, 30, 3);
  const std::string path = temp_path("lonlat.tif");
  RasterOptions options;
  options.layout = RasterOptions::Layout::lonlat;
  write_raster(path, f.labels(), f.table, options);
  Opened opened(path);
  GDALDatasetH ds = opened.ds;
  ASSERT_NE(ds, nullptr);
  const int I = 1 << f.level;
  ASSERT_EQ(GDALGetRasterXSize(ds), 4 * I);  // default: square pixels of 90/2^L degrees
  ASSERT_EQ(GDALGetRasterYSize(ds), 2 * I);
  EXPECT_EQ(metadata(ds, "QTM_LAYOUT"), "lonlat");
  EXPECT_EQ(metadata(ds, "QTM_LEVEL"), std::to_string(f.level));
  double gt[6];
  ASSERT_EQ(GDALGetGeoTransform(ds, gt), CE_None);
  const double res = 90.0 / I;
  EXPECT_EQ(gt[0], -180.0);
  EXPECT_EQ(gt[1], res);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[3], 90.0);
  EXPECT_EQ(gt[4], 0.0);
  EXPECT_EQ(gt[5], -res);
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
  ASSERT_NE(srs, nullptr);
  EXPECT_STREQ(OSRGetAuthorityName(srs, nullptr), "EPSG");
  EXPECT_STREQ(OSRGetAuthorityCode(srs, nullptr), "4326");

  const std::vector<double> fid = read_band(ds, 1), boundary = read_band(ds, 2), distance = read_band(ds, 3);
  const int w = 4 * I, h = 2 * I;
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> px(0, w - 1), py(0, h - 1);
  for (int k = 0; k < 4000; ++k) {
    // Edges and corners too: the first/last rows and columns hold the poles and the antimeridian.
    const int x = k < 4 ? (k % 2) * (w - 1) : px(rng);
    const int y = k < 4 ? (k / 2) * (h - 1) : py(rng);
    const double lon = gt[0] + (x + 0.5) * gt[1], lat = gt[3] + (y + 0.5) * gt[5];
    const Code code = grid::lonlat_to_code(lon, lat, f.level);
    ASSERT_NE(code, grid::kInvalidCode);
    const std::size_t p = static_cast<std::size_t>(y) * w + x;
    ASSERT_EQ(fid[p], Fixture::fid_of(f.result.site[code])) << "pixel " << x << "," << y;
    ASSERT_EQ(boundary[p], f.result.boundary[code]) << "pixel " << x << "," << y;
    ASSERT_EQ(distance[p], static_cast<double>(f.result.distance_m[code])) << "pixel " << x << "," << y;
  }
}

TEST_F(RasterWriter, LonLatHonoursTsAndTr) {
  const Fixture f(4, 10, 9);
  RasterOptions options;
  options.layout = RasterOptions::Layout::lonlat;
  {
    options.width = 500;
    options.height = 200;
    const std::string path = temp_path("ts.tif");
    write_raster(path, f.labels(), f.table, options);
    Opened opened(path);
    ASSERT_NE(opened.ds, nullptr);
    EXPECT_EQ(GDALGetRasterXSize(opened.ds), 500);
    EXPECT_EQ(GDALGetRasterYSize(opened.ds), 200);
    double gt[6];
    ASSERT_EQ(GDALGetGeoTransform(opened.ds, gt), CE_None);
    EXPECT_DOUBLE_EQ(gt[1], 360.0 / 500);
    EXPECT_DOUBLE_EQ(gt[5], -180.0 / 200);
    // A pixel at the far south-east agrees with point location there.
    const double lon = -180.0 + 499.5 * gt[1], lat = 90.0 - 199.5 * -gt[5];
    EXPECT_EQ(read_pixel(opened.ds, 1, 499, 199),
              Fixture::fid_of(f.result.site[grid::lonlat_to_code(lon, lat, f.level)]));
  }
  {
    options.width = options.height = 0;
    options.x_resolution = 0.7;  // 360 / 0.7 = 514.3: rounded, the resolution kept
    options.y_resolution = 2.0;
    const std::string path = temp_path("tr.tif");
    write_raster(path, f.labels(), f.table, options);
    Opened opened(path);
    ASSERT_NE(opened.ds, nullptr);
    EXPECT_EQ(GDALGetRasterXSize(opened.ds), 514);
    EXPECT_EQ(GDALGetRasterYSize(opened.ds), 90);
    double gt[6];
    ASSERT_EQ(GDALGetGeoTransform(opened.ds, gt), CE_None);
    EXPECT_EQ(gt[1], 0.7);
    EXPECT_EQ(gt[5], -2.0);
  }
  options.width = 10;  // with -tr too
  EXPECT_THROW(write_raster(temp_path("both.tif"), f.labels(), f.table, options), WriteError);
  EXPECT_FALSE(exists(temp_path("both.tif")));
}

TEST_F(RasterWriter, GeoTiffCreationOptionsDefaultAndOverridable) {
  const Fixture f(6, 12, 4);
  {
    const std::string path = temp_path("co_default.tif");
    write_raster(path, f.labels(), f.table, RasterOptions{});
    Opened opened(path);
    ASSERT_NE(opened.ds, nullptr);
    EXPECT_EQ(metadata(opened.ds, "COMPRESSION", "IMAGE_STRUCTURE"), "DEFLATE");
    EXPECT_EQ(metadata(opened.ds, "INTERLEAVE", "IMAGE_STRUCTURE"), "BAND");
    int bw = 0, bh = 0;
    GDALGetBlockSize(GDALGetRasterBand(opened.ds, 1), &bw, &bh);
    EXPECT_EQ(bw, 256);  // tiled
    EXPECT_EQ(bh, 256);
  }
  {
    const std::string path = temp_path("co_lzw.tif");
    RasterOptions options;
    options.creation_options = {"COMPRESS=LZW", "tiled=no", "INTERLEAVE=PIXEL"};
    write_raster(path, f.labels(), f.table, options);
    Opened opened(path);
    ASSERT_NE(opened.ds, nullptr);
    EXPECT_EQ(metadata(opened.ds, "COMPRESSION", "IMAGE_STRUCTURE"), "LZW");
    EXPECT_EQ(metadata(opened.ds, "INTERLEAVE", "IMAGE_STRUCTURE"), "PIXEL");
    int bw = 0, bh = 0;
    GDALGetBlockSize(GDALGetRasterBand(opened.ds, 1), &bw, &bh);
    EXPECT_EQ(bw, GDALGetRasterXSize(opened.ds));  // strips
    check_qtm_raster(opened.ds, f, true);
  }
}

TEST_F(RasterWriter, CreateCopyOnlyDriverGoesThroughStaging) {
  if (GDALGetDriverByName("COG") == nullptr) GTEST_SKIP() << "no COG driver";
  const Fixture f(5, 20, 8);
  const std::string path = temp_path("cog.tif");
  RasterOptions options;
  options.driver = "COG";
  double last = -1;
  options.progress = [&](double fraction, const char*) {
    EXPECT_GE(fraction, last);
    last = fraction;
    return true;
  };
  write_raster(path, f.labels(), f.table, options);
  EXPECT_DOUBLE_EQ(last, 1.0);
  Opened opened(path);
  check_qtm_raster(opened.ds, f, true);
}

TEST_F(RasterWriter, CogOverviewsOfTheFidBandHoldOnlySiteFids) {
  // The COG driver's default overview resampling (CUBIC) made FIDs that are no site.
  if (GDALGetDriverByName("COG") == nullptr) GTEST_SKIP() << "no COG driver";
  const Fixture f(6, 20, 8);
  const std::string path = temp_path("cog_overviews.tif");
  RasterOptions options;
  options.driver = "COG";
  options.creation_options = {"BLOCKSIZE=16"};  // overviews even for this small raster
  write_raster(path, f.labels(), f.table, options);
  Opened opened(path);
  ASSERT_TRUE(opened.ds);
  std::set<double> allowed{-1.0};  // nodata
  for (int s = 0; s < 20; ++s) allowed.insert(static_cast<double>(Fixture::fid_of(s)));
  GDALRasterBandH band = GDALGetRasterBand(opened.ds, 1);
  ASSERT_GT(GDALGetOverviewCount(band), 0);
  for (int o = 0; o < GDALGetOverviewCount(band); ++o) {
    GDALRasterBandH overview = GDALGetOverview(band, o);
    const int w = GDALGetRasterBandXSize(overview), h = GDALGetRasterBandYSize(overview);
    std::vector<double> values(static_cast<std::size_t>(w) * h);
    ASSERT_EQ(GDALRasterIO(overview, GF_Read, 0, 0, w, h, values.data(), w, h, GDT_Float64, 0, 0), CE_None);
    for (const double v : values) ASSERT_TRUE(allowed.count(v)) << "overview " << o << " holds FID " << v;
  }
}

TEST_F(RasterWriter, InterruptedLeavesNothing) {
  const Fixture f(7, 10, 2);
  for (const char* driver : {"GTiff", "COG"}) {
    if (GDALGetDriverByName(driver) == nullptr) continue;
    SCOPED_TRACE(driver);
    const std::string path = temp_path(std::string("interrupted_") + driver + ".tif");
    RasterOptions options;
    options.driver = driver;
    // GTiff: stop after the strips are written (before closing); COG: during CreateCopy.
    const double stop_after = std::string(driver) == "COG" ? 0.5 : 0.99;
    options.progress = [&](double fraction, const char*) { return fraction <= stop_after; };
    try {
      write_raster(path, f.labels(), f.table, options);
      FAIL() << "no error";
    } catch (const Interrupted&) {
      SUCCEED();  // a stop, not a failure
    }
    EXPECT_FALSE(exists(path));
    EXPECT_FALSE(exists(path + ".staging.tif"));
  }
}

TEST_F(RasterWriter, FailuresAreClearWriteErrors) {
  const Fixture f(3, 5, 1);
  auto message_of = [&](const std::string& path, const RasterOptions& options) -> std::string {
    try {
      write_raster(path, f.labels(), f.table, options);
    } catch (const WriteError& e) {
      std::printf("  WriteError: %s\n", e.what());
      return e.what();
    }
    ADD_FAILURE() << "no WriteError for " << path;
    VSIUnlink(path.c_str());
    return "";
  };
  {
    const std::string path = temp_path("no_such_dir/out.tif");
    const std::string m = message_of(path, RasterOptions{});
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find("cannot create"), std::string::npos) << m;
  }
  {
    RasterOptions options;
    options.driver = "NoSuchDriver";
    const std::string m = message_of(temp_path("x.tif"), options);
    EXPECT_NE(m.find("unknown raster driver 'NoSuchDriver'"), std::string::npos) << m;
  }
  {
    RasterOptions options;
    options.driver = "PNG";  // Byte and UInt16 only: the FIDs would be truncated
    const std::string path = temp_path("x.png");
    const std::string m = message_of(path, options);
    EXPECT_NE(m.find("PNG cannot hold Float32"), std::string::npos) << m;
    EXPECT_NE(m.find("-ot"), std::string::npos) << m;
    EXPECT_FALSE(exists(path));
  }
  {
    sites::SiteTable negative;
    negative.sites.resize(f.table.sites.size());
    for (std::size_t s = 0; s < negative.sites.size(); ++s) negative.sites[s].fid = f.table.sites[s].fid;
    negative.sites[1].fid = -5;
    try {
      write_raster(temp_path("negfid.tif"), f.labels(), negative, RasterOptions{});
      ADD_FAILURE() << "no WriteError for a negative FID";
    } catch (const WriteError& e) {
      EXPECT_NE(std::string(e.what()).find("band 1 (site_fid): site 1 has FID -5"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(exists(temp_path("negfid.tif")));
  }
  {
    RasterOptions options;
    options.width = 100;  // -ts with the qtm layout
    EXPECT_NE(message_of(temp_path("ts_qtm.tif"), options).find("lonlat only"), std::string::npos);
  }
}

// --- streaming, band types ----------------------------------------------------------------------

/// The labeller's session as a CellLabelSource: the writer streams from the labeller itself.
class SessionSource : public CellLabelSource {
 public:
  SessionSource(const label::SiteGeometry& g, bool with_distance) : session_(g.input(), options(with_distance)) {}
  int level() const override { return session_.level(); }
  bool has_distance() const override { return session_.has_distance(); }
  void label_range(Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    ++calls;
    session_.label_range(first, count, site, distance_m, boundary);
  }
  void label_codes(const Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    ++calls;
    session_.label_codes(codes, count, site, distance_m, boundary);
  }
  void label_parallels(const double* lat, int rows, const double* lon, std::size_t count, std::int32_t* site,
                       float* distance_m, std::uint8_t* boundary) const override {
    ++calls;
    session_.label_parallels(lat, rows, lon, count, site, distance_m, boundary);
  }
  mutable int calls = 0;

 private:
  static label::LabelOptions options(bool with_distance) {
    label::LabelOptions o;
    o.device = "cpu";
    o.want_distance = with_distance;
    return o;
  }
  label::LabelSession session_;
};

/// The cell a pixel shows (kInvalidCode: nodata), from the raster's layout and geotransform.
Code pixel_code(const double* gt, int level, bool qtm, int x, int y) {
  if (qtm) {
    const int I = 1 << level;
    const int octant = y / I, i = y % I;
    if (x > 2 * i) return grid::kInvalidCode;
    return grid::code_of({octant, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(x)}, level);
  }
  return grid::lonlat_to_code(gt[0] + (x + 0.5) * gt[1], gt[3] + (y + 0.5) * gt[5], level);
}

std::vector<double> geotransform(GDALDatasetH ds) {
  std::vector<double> gt(6, 0.0);
  GDALGetGeoTransform(ds, gt.data());
  return gt;
}

/// Every pixel against the whole-globe labels of the fixture; returns the mismatches (and
/// reports the first few).
std::uint64_t compare_with_dense(GDALDatasetH ds, const Fixture& f, bool qtm) {
  if (ds == nullptr) {
    ADD_FAILURE() << "no dataset";
    return 1;
  }
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  const std::vector<double> fid = read_band(ds, 1), boundary = read_band(ds, 2), distance = read_band(ds, 3);
  const std::vector<double> gt = geotransform(ds);
  std::uint64_t bad = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * w + x;
      const Code code = pixel_code(gt.data(), f.level, qtm, x, y);
      bool ok;
      if (code == grid::kInvalidCode) {
        ok = fid[p] == -1 && boundary[p] == -1 && distance[p] == -1;
      } else {
        ok = fid[p] == static_cast<double>(Fixture::fid_of(f.result.site[code])) &&
             boundary[p] == f.result.boundary[code] && distance[p] == static_cast<double>(f.result.distance_m[code]);
      }
      if (!ok && ++bad <= 3) ADD_FAILURE() << "pixel " << x << "," << y << " (cell " << code << ")";
    }
  }
  return bad;
}

TEST_F(RasterWriter, StreamedStripsEqualTheWholeGlobeAtLevels3To7) {
  struct Grid {
    const char* name;
    bool qtm;
    int width, height;
    double xres, yres;
  };
  for (int level = 3; level <= 7; ++level) {
    const Fixture f(level, 4 + 6 * level, 300 + level);
    label::SiteGeometry g;  // the fixture's sites again, for a session
    g.level = level;
    {
      std::mt19937_64 rng(300 + level);
      std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
      for (int s = 0; s < 4 + 6 * level; ++s) add_point(g, lon(rng), std::asin(z(rng)) * 180.0 / M_PI, s);
    }
    const SessionSource session(g, true);
    const int I = 1 << level;
    const Grid grids[] = {
        {"qtm", true, 0, 0, 0, 0},
        {"lonlat default", false, 0, 0, 0, 0},
        {"lonlat -ts 500 200", false, 500, 200, 0, 0},     // coarse at 6-7: the strips' code lists
        {"lonlat -ts 8I 4I", false, 8 * I, 4 * I, 0, 0},  // finer than the cells: rows of cells
        {"lonlat -tr 0.7 2", false, 0, 0, 0.7, 2.0},
    };
    for (const Grid& grid_options : grids) {
      // One row a strip (up to level 5), a few rows, and the default (the whole raster here).
      for (const std::uint64_t strip_bytes : {std::uint64_t{1}, std::uint64_t{20000}, std::uint64_t{0}}) {
        if (strip_bytes == 1 && level > 5) continue;
        SCOPED_TRACE("level " + std::to_string(level) + ", " + grid_options.name + ", strip budget " +
                     std::to_string(strip_bytes));
        RasterOptions options;
        options.layout = grid_options.qtm ? RasterOptions::Layout::qtm : RasterOptions::Layout::lonlat;
        options.width = grid_options.width;
        options.height = grid_options.height;
        options.x_resolution = grid_options.xres;
        options.y_resolution = grid_options.yres;
        options.strip_bytes = strip_bytes;
        int strips = 0;
        options.progress = [&](double, const char*) {
          ++strips;
          return true;
        };
        const std::string dense_path = temp_path("dense.tif"), streamed_path = temp_path("streamed.tif");
        write_raster(dense_path, f.labels(), f.table, options);
        const int calls_before = session.calls;
        strips = 0;
        write_raster(streamed_path, session, f.table, options);
        const RasterSize size = raster_size(level, options);
        if (strip_bytes == 1) {
          EXPECT_EQ(strips, size.height + 1);  // one row a strip, and 0%
        }
        EXPECT_GE(session.calls - calls_before, strips - 1);       // asked strip by strip
        Opened dense(dense_path), streamed(streamed_path);
        EXPECT_EQ(compare_with_dense(dense.ds, f, grid_options.qtm), 0u);
        EXPECT_EQ(compare_with_dense(streamed.ds, f, grid_options.qtm), 0u);
      }
    }
  }
}

/// Chosen values for the band types: site = code % sites (FIDs 10 s + 3), distances with
/// quarters of a metre (rounded to even by integer types), boundary = code % 2.
class ChosenValues : public CellLabelSource {
 public:
  ChosenValues(int level, int sites, float metres_scale) : level_(level), sites_(sites), scale_(metres_scale) {}
  int level() const override { return level_; }
  bool has_distance() const override { return true; }
  void label_range(Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    for (std::uint64_t k = 0; k < count; ++k) put(first + k, k, site, distance_m, boundary);
  }
  void label_codes(const Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    for (std::size_t k = 0; k < count; ++k) put(codes[k], k, site, distance_m, boundary);
  }
  std::int32_t site_of(Code c) const { return static_cast<std::int32_t>(c % sites_); }
  float metres_of(Code c) const { return static_cast<float>(c % 200) * scale_ + static_cast<float>(c % 4) * 0.25f; }
  sites::SiteTable table() const {
    sites::SiteTable t;
    t.sites.resize(static_cast<std::size_t>(sites_));
    for (int s = 0; s < sites_; ++s) t.sites[s].fid = 10 * s + 3;
    return t;
  }

 private:
  void put(Code c, std::size_t k, std::int32_t* site, float* distance_m, std::uint8_t* boundary) const {
    site[k] = site_of(c);
    if (distance_m) distance_m[k] = metres_of(c);
    boundary[k] = static_cast<std::uint8_t>(c % 2);
  }
  int level_, sites_;
  float scale_;
};

TEST_F(RasterWriter, EveryOtTypeRoundTrips) {
  const ChosenValues values(4, 7, 1.0f);  // FIDs 3..63, distances 0..199.75 m: every type holds them
  const sites::SiteTable table = values.table();
  const struct {
    const char* name;
    GDALDataType type;
    double nodata;
  } types[] = {{"Byte", GDT_Byte, 255},      {"uint16", GDT_UInt16, 65535}, {"Int16", GDT_Int16, -1},
               {"UInt32", GDT_UInt32, 4294967295.0}, {"INT32", GDT_Int32, -1}, {"Float32", GDT_Float32, -1},
               {"Float64", GDT_Float64, -1}};
  for (const auto& t : types) {
    SCOPED_TRACE(t.name);
    EXPECT_EQ(raster_nodata(GDALGetDataTypeName(t.type)), t.nodata);
    for (const bool qtm : {true, false}) {
      RasterOptions options;
      options.data_type = t.name;
      options.layout = qtm ? RasterOptions::Layout::qtm : RasterOptions::Layout::lonlat;
      options.strip_bytes = 5000;
      EXPECT_EQ(raster_data_type(options, true, table), GDALGetDataTypeName(t.type));
      const std::string path = temp_path(std::string("ot_") + t.name + ".tif");
      write_raster(path, values, table, options);
      Opened opened(path);
      ASSERT_NE(opened.ds, nullptr);
      const int w = GDALGetRasterXSize(opened.ds), h = GDALGetRasterYSize(opened.ds);
      std::vector<double> band[3];
      for (int b = 0; b < 3; ++b) {
        GDALRasterBandH hb = GDALGetRasterBand(opened.ds, b + 1);
        EXPECT_EQ(GDALGetRasterDataType(hb), t.type);
        int has = 0;
        EXPECT_EQ(GDALGetRasterNoDataValue(hb, &has), t.nodata);
        EXPECT_TRUE(has);
        band[b] = read_band(opened.ds, b + 1);
      }
      const std::vector<double> gt = geotransform(opened.ds);
      int bad = 0;
      for (int y = 0; y < h && bad < 5; ++y) {
        for (int x = 0; x < w && bad < 5; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * w + x;
          const Code code = pixel_code(gt.data(), 4, qtm, x, y);
          double fid = t.nodata, flag = t.nodata, metres = t.nodata;
          if (code != grid::kInvalidCode) {
            fid = static_cast<double>(table.sites[values.site_of(code)].fid);
            flag = static_cast<double>(code % 2);
            const double d = values.metres_of(code);
            metres = t.type == GDT_Float32 || t.type == GDT_Float64 ? d : std::nearbyint(d);
          }
          if (band[0][p] != fid || band[1][p] != flag || band[2][p] != metres) {
            ADD_FAILURE() << "pixel " << x << "," << y << ": " << band[0][p] << " " << band[1][p] << " " << band[2][p]
                          << " vs " << fid << " " << flag << " " << metres;
            ++bad;
          }
        }
      }
    }
  }
}

TEST_F(RasterWriter, DefaultTypeKeepsEveryFidExact) {
  const ChosenValues values(3, 4, 1.0f);
  sites::SiteTable table = values.table();
  RasterOptions options;
  EXPECT_EQ(raster_data_type(options, true, table), "Float32");
  EXPECT_EQ(raster_data_type(options, false, table), "Int32");
  table.sites[2].fid = (std::int64_t{1} << 24) + 1;  // not a float
  EXPECT_EQ(raster_data_type(options, true, table), "Float64");
  EXPECT_EQ(raster_data_type(options, false, table), "Int32");
  table.sites[2].fid = std::int64_t{1} << 31;  // beyond Int32, but a float
  EXPECT_EQ(raster_data_type(options, true, table), "Float32");
  EXPECT_EQ(raster_data_type(options, false, table), "Float64");
  table.sites[2].fid = (std::int64_t{1} << 40) + 1;
  const std::string path = temp_path("default_f64.tif");
  write_raster(path, values, table, options);
  Opened opened(path);
  ASSERT_NE(opened.ds, nullptr);
  EXPECT_EQ(GDALGetRasterDataType(GDALGetRasterBand(opened.ds, 1)), GDT_Float64);
  const std::vector<double> fid = read_band(opened.ds, 1);
  EXPECT_NE(std::find(fid.begin(), fid.end(), static_cast<double>((std::int64_t{1} << 40) + 1)), fid.end());
}

TEST_F(RasterWriter, ValuesOutsideTheOtTypeFailNamingItAndLeaveNoFile) {
  auto message_of = [&](const CellLabelSource& source, const sites::SiteTable& table, const std::string& type) {
    RasterOptions options;
    options.data_type = type;
    options.strip_bytes = 3000;
    const std::string path = temp_path("range_" + type + ".tif");
    std::string message;
    try {
      write_raster(path, source, table, options);
      ADD_FAILURE() << "no WriteError for -ot " << type;
    } catch (const WriteError& e) {
      message = e.what();
    }
    EXPECT_FALSE(exists(path)) << path;
    EXPECT_NE(message.find(path), std::string::npos) << message;
    return message;
  };
  const ChosenValues values(4, 5, 1.0f);
  for (const auto& [type, fid] : std::vector<std::pair<std::string, std::int64_t>>{
           {"Byte", 300}, {"Byte", 255}, {"UInt16", 65535}, {"Int16", 40000}, {"UInt32", 4294967295}, {"Int32", 2147483648},
           {"Float32", 16777217}}) {
    SCOPED_TRACE(type + " " + std::to_string(fid));
    sites::SiteTable table = values.table();
    table.sites[3].fid = fid;
    const std::string m = message_of(values, table, type);
    EXPECT_NE(m.find("band 1 (site_fid): site 3 has FID " + std::to_string(fid)), std::string::npos) << m;
    EXPECT_NE(m.find("-ot"), std::string::npos) << m;
    EXPECT_NE(m.find(type), std::string::npos) << m;
  }
  {
    // Largest FIDs that fit.
    sites::SiteTable table = values.table();
    table.sites[3].fid = 254;
    RasterOptions options;
    options.data_type = "Byte";
    EXPECT_EQ(raster_data_type(options, true, table), "Byte");
  }
  // Distances beyond the type, found while writing: the output is removed.
  const ChosenValues far(4, 5, 400.0f);  // up to 79600 m
  for (const std::string type : {"Byte", "UInt16", "Int16"}) {
    SCOPED_TRACE(type);
    const std::string m = message_of(far, far.table(), type);
    EXPECT_NE(m.find("band 3 (distance_m): cell "), std::string::npos) << m;
    EXPECT_NE(m.find(" m from its site, outside " + type), std::string::npos) << m;
    EXPECT_NE(m.find("-ot"), std::string::npos) << m;
  }
  {
    // A lon/lat raster of pixels coarser than the cells, labelled pixel by pixel: the cell named is
    // a pixel's, with the distance named.
    SCOPED_TRACE("lonlat by pixel");
    RasterOptions options;
    options.layout = RasterOptions::Layout::lonlat;
    options.width = 40;
    options.height = 20;
    options.data_type = "Byte";
    const std::string path = temp_path("far_lonlat.tif");
    std::string m;
    try {
      write_raster(path, far, far.table(), options);
      ADD_FAILURE() << "no WriteError";
    } catch (const WriteError& e) {
      m = e.what();
    }
    EXPECT_FALSE(exists(path)) << path;
    const std::size_t at = m.find("band 3 (distance_m): cell ");
    ASSERT_NE(at, std::string::npos) << m;
    const Code code = std::stoull(m.substr(at + std::strlen("band 3 (distance_m): cell ")));
    bool a_pixels_cell = false;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        a_pixels_cell = a_pixels_cell || grid::lonlat_to_code(-180.0 + (x + 0.5) * 9.0, 90.0 - (y + 0.5) * 9.0, 4) == code;
      }
    }
    EXPECT_TRUE(a_pixels_cell) << m;
    char metres[64];
    std::snprintf(metres, sizeof metres, " is %.1f m from its site", static_cast<double>(far.metres_of(code)));
    EXPECT_NE(m.find(metres), std::string::npos) << m;
  }
  EXPECT_NO_THROW(check_raster_data_type("float32"));
  EXPECT_NO_THROW(check_raster_data_type(""));
  try {
    check_raster_data_type("Int8");
    ADD_FAILURE() << "Int8 accepted";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("-ot: 'Int8' is not one of Byte, UInt16, Int16, UInt32, Int32, Float32, Float64"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(RasterWriter, StreamedStopAndCogStagingLeaveNothingBehind) {
  const Fixture f(7, 25, 11);
  label::SiteGeometry g;
  g.level = 7;
  {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
    for (int s = 0; s < 25; ++s) add_point(g, lon(rng), std::asin(z(rng)) * 180.0 / M_PI, s);
  }
  const SessionSource session(g, true);
  for (const char* driver : {"GTiff", "COG"}) {
    if (GDALGetDriverByName(driver) == nullptr) continue;
    SCOPED_TRACE(driver);
    RasterOptions options;
    options.driver = driver;
    options.strip_bytes = 30000;  // many strips; COG stages on disk (larger than a strip)
    const std::string path = temp_path(std::string("stream_stop_") + driver + ".tif");
    options.progress = [&](double fraction, const char*) {
      // No staging file in memory: the staging GeoTIFF is on disk while the strips are written.
      if (std::string(driver) == "COG" && fraction > 0.1 && fraction < 0.5) {
        EXPECT_TRUE(exists(path + ".staging.tif"));
      }
      return fraction < 0.3;
    };
    EXPECT_THROW(write_raster(path, session, f.table, options), Interrupted);
    EXPECT_FALSE(exists(path));
    EXPECT_FALSE(exists(path + ".staging.tif"));
    // Written through to the end, it equals the whole-globe labels; the staging copy is gone.
    options.progress = {};
    write_raster(path, session, f.table, options);
    EXPECT_FALSE(exists(path + ".staging.tif"));
    Opened opened(path);
    EXPECT_EQ(compare_with_dense(opened.ds, f, true), 0u);
    if (std::string(driver) == "COG") {
      EXPECT_EQ(metadata(opened.ds, "LAYOUT", "IMAGE_STRUCTURE"), "COG");
    }
  }
}

// --- -bands, threads ----------------------------------------------------------------------------

/// A band's values as the bytes of its type.
std::vector<unsigned char> band_bytes(GDALDatasetH ds, int band) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  GDALRasterBandH hb = GDALGetRasterBand(ds, band);
  const GDALDataType type = GDALGetRasterDataType(hb);
  std::vector<unsigned char> bytes(static_cast<std::size_t>(w) * h * GDALGetDataTypeSizeBytes(type));
  EXPECT_EQ(GDALRasterIO(hb, GF_Read, 0, 0, w, h, bytes.data(), w, h, type, 0, 0), CE_None);
  return bytes;
}

std::vector<unsigned char> file_bytes(const std::string& path) {
  std::vector<unsigned char> bytes;
  VSILFILE* f = VSIFOpenL(path.c_str(), "rb");
  if (f == nullptr) return bytes;
  VSIFSeekL(f, 0, SEEK_END);
  bytes.resize(static_cast<std::size_t>(VSIFTellL(f)));
  VSIFSeekL(f, 0, SEEK_SET);
  EXPECT_EQ(VSIFReadL(bytes.data(), 1, bytes.size(), f), bytes.size());
  VSIFCloseL(f);
  return bytes;
}

/// A Fixture's labels as a CellLabelSource that records which labels it is asked for.
class AskedSource : public CellLabelSource {
 public:
  explicit AskedSource(const CellLabels& labels) : dense_(labels) {}
  int level() const override { return dense_.level(); }
  bool has_distance() const override { return dense_.has_distance(); }
  void label_range(Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    note(distance_m, boundary);
    dense_.label_range(first, count, site, distance_m, boundary);
  }
  void label_codes(const Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    note(distance_m, boundary);
    dense_.label_codes(codes, count, site, distance_m, boundary);
  }
  mutable bool distance_asked = false, boundary_asked = false;

 private:
  void note(const float* distance_m, const std::uint8_t* boundary) const {
    distance_asked = distance_asked || distance_m != nullptr;
    boundary_asked = boundary_asked || boundary != nullptr;
  }
  DenseLabelSource dense_;
};

TEST_F(RasterWriter, BandsSubsetsEqualTheMatchingBandsOfTheFullRasterByteForByte) {
  const Fixture f(6, 40, 7);
  using B = RasterBand;
  const std::vector<std::vector<RasterBand>> subsets = {
      {B::fid}, {B::boundary}, {B::distance}, {B::distance, B::fid}, {B::boundary, B::distance, B::fid},
      {B::fid, B::boundary}, {B::fid, B::boundary, B::distance}};
  const char* descriptions[] = {"site_fid", "boundary", "distance_m"};
  for (const bool qtm : {true, false}) {
    for (const char* type : {"Float32", "Int32"}) {
      SCOPED_TRACE(std::string(qtm ? "qtm " : "lonlat ") + type);
      RasterOptions options;
      options.layout = qtm ? RasterOptions::Layout::qtm : RasterOptions::Layout::lonlat;
      if (!qtm) options.width = 700, options.height = 310;  // pixels about as fine as the cells
      options.data_type = type;                             // the full raster's type for every subset
      options.strip_bytes = 40000;                          // many strips
      const std::string full_path = temp_path("bands_full.tif");
      write_raster(full_path, f.labels(), f.table, options);
      Opened full(full_path);
      ASSERT_NE(full.ds, nullptr);
      ASSERT_EQ(GDALGetRasterCount(full.ds), 3);
      const std::vector<double> full_gt = geotransform(full.ds);
      for (const std::vector<RasterBand>& bands : subsets) {
        std::string names;
        for (const RasterBand b : bands) names += std::string(names.empty() ? "" : ",") + raster_band_name(b);
        SCOPED_TRACE(names);
        options.bands = bands;
        const AskedSource source(f.labels());
        const std::string path = temp_path("bands_subset.tif");
        write_raster(path, source, f.table, options);
        // Only the labels the bands need were asked for.
        EXPECT_EQ(source.distance_asked, has_band(bands, B::distance));
        EXPECT_EQ(source.boundary_asked, has_band(bands, B::boundary));
        Opened subset(path);
        ASSERT_NE(subset.ds, nullptr);
        ASSERT_EQ(GDALGetRasterCount(subset.ds), static_cast<int>(bands.size()));
        EXPECT_EQ(geotransform(subset.ds), full_gt);
        EXPECT_EQ(metadata(subset.ds, "QTM_LEVEL"), "6");
        EXPECT_EQ(metadata(subset.ds, "QTM_LAYOUT"), qtm ? "octant_row_col" : "lonlat");
        for (std::size_t k = 0; k < bands.size(); ++k) {
          const int in_full = static_cast<int>(bands[k]) + 1;
          GDALRasterBandH band = GDALGetRasterBand(subset.ds, static_cast<int>(k) + 1);
          EXPECT_STREQ(GDALGetDescription(band), descriptions[in_full - 1]);
          EXPECT_STREQ(GDALGetDescription(band), raster_band_description(bands[k]));
          EXPECT_STREQ(GDALGetRasterUnitType(band), bands[k] == B::distance ? "m" : "");
          int has_nodata = 0;
          EXPECT_EQ(GDALGetRasterNoDataValue(band, &has_nodata), -1.0);
          EXPECT_TRUE(has_nodata);
          EXPECT_TRUE(band_bytes(subset.ds, static_cast<int>(k) + 1) == band_bytes(full.ds, in_full))
              << "band " << k + 1 << " differs from band " << in_full << " of the full raster";
        }
      }
    }
  }
}

TEST_F(RasterWriter, BandsChooseTheirDefaultTypeAndKeepTheOtChecks) {
  const Fixture f(4, 20, 5);  // FIDs 1000 .. 1133
  using B = RasterBand;
  RasterOptions options;
  const auto type_of = [&](std::vector<RasterBand> bands, const std::string& ot = "") {
    options.bands = std::move(bands);
    options.data_type = ot;
    return raster_data_type(options, true, f.table);
  };
  EXPECT_EQ(type_of({}), "Float32");
  EXPECT_EQ(type_of({B::fid}), "Int32");
  EXPECT_EQ(type_of({B::fid, B::boundary}), "Int32");
  EXPECT_EQ(type_of({B::boundary}), "Byte");
  EXPECT_EQ(type_of({B::distance}), "Float32");
  EXPECT_EQ(type_of({B::boundary, B::distance}), "Float32");
  // An allocation raster's FIDs are checked against -ot as ever; without the FID band none is.
  try {
    type_of({B::distance, B::fid}, "Byte");
    ADD_FAILURE() << "FID 1000 accepted as Byte";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("band 2 (site_fid): site 0 has FID 1000, which Byte does not hold exactly"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(type_of({B::fid}, "Byte"), WriteError);
  EXPECT_EQ(type_of({B::boundary}, "Byte"), "Byte");
  // A distance the type cannot hold, with the distance band alone: named by its band, nothing left.
  options.bands = {B::distance};
  options.data_type = "Int16";
  const std::string path = temp_path("bands_far.tif");
  try {
    write_raster(path, f.labels(), f.table, options);
    ADD_FAILURE() << "distances beyond Int16 accepted";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("band 1 (distance_m): cell "), std::string::npos) << e.what();
  }
  EXPECT_FALSE(exists(path));
  // The boundary band alone, in Byte: the labeller's flags.
  options.bands = {B::boundary};
  options.data_type.clear();
  write_raster(path, f.labels(), f.table, options);
  {
    Opened opened(path);
    ASSERT_NE(opened.ds, nullptr);
    GDALRasterBandH band = GDALGetRasterBand(opened.ds, 1);
    EXPECT_EQ(GDALGetRasterDataType(band), GDT_Byte);
    int has_nodata = 0;
    EXPECT_EQ(GDALGetRasterNoDataValue(band, &has_nodata), 255.0);
    const std::vector<double> flags = read_band(opened.ds, 1);
    const int w = GDALGetRasterXSize(opened.ds);
    for (int y = 0; y < GDALGetRasterYSize(opened.ds); ++y) {
      for (int x = 0; x < w; ++x) {
        const Code code = pixel_code(nullptr, 4, true, x, y);
        ASSERT_EQ(flags[static_cast<std::size_t>(y) * w + x],
                  code == grid::kInvalidCode ? 255.0 : static_cast<double>(f.result.boundary[code]));
      }
    }
  }
  // Bands the labels cannot give, or listed twice.
  options.bands = {B::fid, B::distance};
  EXPECT_THROW(write_raster(path, f.labels(false, true), f.table, options), WriteError);
  EXPECT_FALSE(exists(path));
  options.bands = {B::fid, B::boundary, B::fid};
  EXPECT_THROW(write_raster(path, f.labels(), f.table, options), WriteError);
  // Without distances the default is fid and boundary, as before -bands.
  EXPECT_EQ(raster_bands(RasterOptions{}, false), (std::vector<RasterBand>{B::fid, B::boundary}));
  EXPECT_EQ(raster_bands(RasterOptions{}, true), (std::vector<RasterBand>{B::fid, B::boundary, B::distance}));
}

TEST_F(RasterWriter, BandsListsParseInOrderAndBadOnesNameTheArgument) {
  using B = RasterBand;
  EXPECT_EQ(parse_raster_bands("fid"), std::vector<RasterBand>{B::fid});
  EXPECT_EQ(parse_raster_bands("distance, FID"), (std::vector<RasterBand>{B::distance, B::fid}));
  EXPECT_EQ(parse_raster_bands("boundary,fid,distance"), (std::vector<RasterBand>{B::boundary, B::fid, B::distance}));
  const auto message_of = [](const std::string& list) {
    try {
      parse_raster_bands(list);
    } catch (const WriteError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message_of("fid,fid"), "-bands: 'fid,fid': band 'fid' named twice");
  EXPECT_EQ(message_of("fid,site_fid"),
            "-bands: 'fid,site_fid': 'site_fid' is not a band; name bands from fid, boundary, distance, separated by commas");
  EXPECT_EQ(message_of(""), "-bands: '': a band name is empty; name bands from fid, boundary, distance, separated by commas");
  EXPECT_EQ(message_of("fid,"),
            "-bands: 'fid,': a band name is empty; name bands from fid, boundary, distance, separated by commas");
}

TEST_F(RasterWriter, OneAndSeveralThreadsWriteTheSameFile) {
  const Fixture f(7, 60, 21);
  for (const bool qtm : {true, false}) {
    for (const bool fid_alone : {false, true}) {
      SCOPED_TRACE(std::string(qtm ? "qtm" : "lonlat") + (fid_alone ? ", -bands fid" : ", every band"));
      RasterOptions options;
      options.layout = qtm ? RasterOptions::Layout::qtm : RasterOptions::Layout::lonlat;
      if (!qtm) options.width = 1500, options.height = 700;
      if (fid_alone) options.bands = {RasterBand::fid};
      // Strips of a few rows, several a row of GeoTIFF's 256-row blocks, and whole rows of blocks.
      for (const std::uint64_t strip_bytes : {std::uint64_t{100000}, std::uint64_t{0}}) {
        options.strip_bytes = strip_bytes;
        std::vector<unsigned char> first;
        for (const int threads : {1, 2, 3, 8}) {
          SCOPED_TRACE(std::to_string(threads) + " threads, strip budget " + std::to_string(strip_bytes));
          const ScopedDefaultThreads scoped(threads);  // the labels', the values' and GDAL's compression
          const std::string path = temp_path("threads_" + std::to_string(threads) + ".tif");
          write_raster(path, f.labels(), f.table, options);
          const std::vector<unsigned char> bytes = file_bytes(path);
          VSIUnlink(path.c_str());
          ASSERT_FALSE(bytes.empty());
          if (threads == 1) {
            first = bytes;
          } else {
            EXPECT_TRUE(bytes == first) << "the file differs from the one written on 1 thread";
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace qtmv::write
