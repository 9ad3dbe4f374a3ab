// The catalogue of bad inputs (docs/RELIABILITY.md): each case runs the built
// qtmvoronoi on data made here, at run time, and checks the exit status, that the message names
// the file, layer, FID or argument, and that a failure leaves neither the destination nor a
// temporary file. A crash or a hang (the runner's time limit) fails the case. Inputs that are
// odd but usable (a polygon round a pole, 10 000 identical points) must give the right output.
#include <signal.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <gtest/gtest.h>

#include "../sites/sites_test_support.hpp"
#include "label/labeller.hpp"
#include "qtmvoronoi_test_support.hpp"

namespace {

namespace fs = std::filesystem;
using qtmv::test::ChildSetup;
using qtmv::test::concat;
using qtmv::test::hidden_entries;
using qtmv::test::test_dir;
using Result = qtmv::test::ProcessResult;
using qtmv::sites::test::make_dataset;
using qtmv::sites::test::TestFeature;

const std::string kTestdata = QTMV_TESTDATA_DIR;
const std::string kCountries = kTestdata + "/world_atlas_countries_110m.gpkg";
const std::string kCentres = kTestdata + "/country_centres.csv";
const std::vector<std::string> kCsvOptions{"-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat"};
constexpr double kEllipsoidArea = 5.10065621724088e14;  // WGS84, m^2

Result run(const std::vector<std::string>& args, const ChildSetup& setup = {}, double timeout = 60) {
  return qtmv::test::run_qtmvoronoi(args, setup, timeout);
}

// Always at a coarse level and on the CPU unless a case says otherwise: the cases are about
// the input, not the work.
Result run_small(const std::vector<std::string>& args, const ChildSetup& setup = {}, double timeout = 60) {
  return run(concat({"-level", "4", "-device", "cpu"}, args), setup, timeout);
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// A GeoJSON FeatureCollection of the given geometry objects (FIDs 0, 1, 2, ...).
std::string geojson(const std::string& path, const std::vector<std::string>& geometries) {
  std::string text = "{\"type\":\"FeatureCollection\",\"features\":[\n";
  for (std::size_t k = 0; k < geometries.size(); ++k) {
    text += std::string(k ? ",\n" : "") + "{\"type\":\"Feature\",\"properties\":{\"n\":" + std::to_string(k) +
            "},\"geometry\":" + geometries[k] + "}";
  }
  return write_text(path, text + "\n]}\n");
}

// A CSV of WKT geometries, without CRS (FIDs 1, 2, 3, ...: the CSV driver counts lines).
std::string wkt_csv(const std::string& path, const std::vector<std::string>& wkts) {
  std::string text = "WKT,n\n";
  for (std::size_t k = 0; k < wkts.size(); ++k) text += "\"" + wkts[k] + "\"," + std::to_string(k) + "\n";
  return write_text(path, text);
}

// A failed run: its status, no crash, no hang, a message naming each of `names` (and the usage
// only for a usage error), and neither the destination nor a temporary directory beside it.
void expect_failure(const Result& r, int status, const std::vector<std::string>& names, const std::string& dst) {
  EXPECT_FALSE(r.timed_out) << "hung: " << r.err;
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << ": " << r.err;
  EXPECT_EQ(r.status, status) << r.err;
  EXPECT_TRUE(contains(r.err, "qtmvoronoi: ")) << r.err;
  for (const std::string& name : names) EXPECT_TRUE(contains(r.err, name)) << "'" << name << "' not in: " << r.err;
  EXPECT_EQ(contains(r.err, "Usage:"), status == 2) << r.err;
  EXPECT_FALSE(fs::exists(dst)) << dst;
  const std::string dir = fs::path(dst).parent_path().string();
  if (fs::is_directory(dir)) {
    EXPECT_TRUE(hidden_entries(dir).empty()) << dir;
  }
}

// A successful run: status 0, the destination in place, no temporary directory, and no GDAL
// error that escaped our messages.
void expect_success(const Result& r, const std::string& dst) {
  EXPECT_FALSE(r.timed_out) << "hung: " << r.err;
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << ": " << r.err;
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(dst)) << dst;
  EXPECT_TRUE(hidden_entries(fs::path(dst).parent_path().string()).empty());
  EXPECT_FALSE(contains(r.err, "ERROR ")) << r.err;
}

struct Region {
  GIntBig fid = 0;
  GIntBig cells = 0;
  double area_fraction = 0;  // of the ellipsoid
};

// The regions layer of a vector output, in site order.
std::vector<Region> regions(const std::string& dst) {
  std::vector<Region> out;
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  if (!ds || !ds->GetLayerByName("regions")) return out;
  for (auto& f : *ds->GetLayerByName("regions")) {
    out.push_back({f->GetFieldAsInteger64("site_fid"), f->GetFieldAsInteger64("cells"),
                   f->GetFieldAsDouble("area_m2") / kEllipsoidArea});
  }
  return out;
}

// Runs the regions of `src` and returns them (an empty list when the run failed).
std::vector<Region> regions_of(const std::string& src, const std::string& dst, const std::vector<std::string>& extra = {}) {
  const Result r = run_small(concat(concat({"-q", "-layers", "regions"}, extra), {src, dst}));
  expect_success(r, dst);
  return regions(dst);
}

std::vector<TestFeature> points(const std::vector<std::string>& wkts) {
  std::vector<TestFeature> out;
  for (std::size_t k = 0; k < wkts.size(); ++k) out.push_back({wkts[k], "f" + std::to_string(k)});
  return out;
}

// A run that succeeds with `message` among its warnings and `kept` regions.
void expect_kept(const std::string& src, const std::string& dst, const std::string& message, std::size_t kept,
                 const std::vector<std::string>& options = {}) {
  const Result r = run_small(concat(concat({"-layers", "regions"}, options), {src, dst}));
  expect_success(r, dst);
  EXPECT_TRUE(contains(r.err, message)) << r.err;
  EXPECT_EQ(regions(dst).size(), kept);
}

// ---------------------------------------------------------------------------------------------
// Files

TEST(CatalogueFiles, MissingFile) {
  const std::string dir = test_dir();
  const Result r = run_small({dir + "/missing.gpkg", dir + "/out.gpkg"});
  expect_failure(r, 1, {"cannot open '" + dir + "/missing.gpkg': no such file"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, EmptyFile) {
  const std::string dir = test_dir();
  const std::string src = write_text(dir + "/empty.gpkg", "");
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1, {"cannot open '" + src + "' as a vector dataset"},
                 dir + "/out.gpkg");
}

TEST(CatalogueFiles, TruncatedGeoPackage) {
  const std::string dir = test_dir();
  const std::string whole = qtmv::test::read_file(kCountries);
  const std::string src = write_text(dir + "/truncated.gpkg", whole.substr(0, 8192));
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1, {"'" + src + "'", "malformed"}, dir + "/out.gpkg");
}

// A shapefile of three points, its sidecars as `remove` leaves them.
std::string shapefile(const std::string& dir, const std::string& remove) {
  const std::string shp = make_dataset(dir + "/pts.shp", "ESRI Shapefile", "pts", "EPSG:4326",
                                       points({"POINT (10 10)", "POINT (-100 40)", "POINT (120 -30)"}));
  if (!remove.empty()) fs::remove(dir + "/pts." + remove);
  return shp;
}

TEST(CatalogueFiles, ShapefileWithoutShx) {
  const std::string dir = test_dir();
  const std::string src = shapefile(dir, "shx");
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1, {"cannot open '" + src + "'", ".shx"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, ShapefileWithoutDbfKeepsItsSitesAndSaysTheAttributesAreGone) {
  const std::string dir = test_dir();
  const std::string src = shapefile(dir, "dbf");
  expect_kept(src, dir + "/out.gpkg", "warning: '" + src + "', layer 'pts': no .dbf beside the .shp", 3);
}

TEST(CatalogueFiles, ShapefileWithoutPrjIsTakenAsWgs84WithAWarning) {
  const std::string dir = test_dir();
  const std::string src = shapefile(dir, "prj");
  expect_kept(src, dir + "/out.gpkg", "warning: '" + src + "', layer 'pts': the layer has no CRS", 3);
}

TEST(CatalogueFiles, DirectoryWithoutData) {
  const std::string dir = test_dir();
  fs::create_directory(dir + "/nothing");
  expect_failure(run_small({dir + "/nothing", dir + "/out.gpkg"}), 1, {"cannot open '" + dir + "/nothing'"},
                 dir + "/out.gpkg");
}

TEST(CatalogueFiles, SpacesAndNonAsciiInBothPaths) {
  const std::string dir = test_dir() + "/dossier d'été ñ";
  fs::create_directory(dir);
  const std::string src = make_dataset(dir + "/villes été.gpkg", "GPKG", "villes", "EPSG:4326",
                                       points({"POINT (2.35 48.85)", "POINT (-3.7 40.4)"}));
  const std::string dst = dir + "/régions 2.gpkg";
  EXPECT_EQ(regions_of(src, dst).size(), 2u);
}

TEST(CatalogueFiles, ZipArchiveThroughVsizip) {
  const std::string dir = test_dir();
  const std::string inside = "/vsizip/" + dir + "/sites.zip/sites.geojson";
  VSILFILE* f = VSIFOpenL(inside.c_str(), "wb");
  ASSERT_TRUE(f);
  const std::string text = qtmv::test::read_file(
      geojson(dir + "/plain.geojson", {R"({"type":"Point","coordinates":[1,2]})", R"({"type":"Point","coordinates":[50,-20]})"}));
  VSIFWriteL(text.data(), 1, text.size(), f);
  VSIFCloseL(f);
  fs::remove(dir + "/plain.geojson");
  EXPECT_EQ(regions_of(inside, dir + "/out.gpkg").size(), 2u);
}

TEST(CatalogueFiles, FileThatIsNotAZipArchive) {
  const std::string dir = test_dir();
  write_text(dir + "/fake.zip", "not a zip archive\n");
  const std::string src = "/vsizip/" + dir + "/fake.zip";
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1, {"cannot open '" + src + "'", "not a readable archive"},
                 dir + "/out.gpkg");
}

TEST(CatalogueFiles, UnreadablePermissions) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/secret.geojson", {R"({"type":"Point","coordinates":[1,2]})"});
  chmod(src.c_str(), 0);
  chmod(dir.c_str(), 0777);  // as root the run drops to nobody, who must still make the temporary directory
  const Result r = run_small({src, dir + "/out.gpkg"}, ChildSetup{-1, true});
  expect_failure(r, 1, {"cannot open '" + src + "'", "Permission denied"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, FifoFailsInsteadOfWaitingForAWriter) {
  const std::string dir = test_dir();
  const std::string src = dir + "/pipe.geojson";
  ASSERT_EQ(mkfifo(src.c_str(), 0644), 0);
  const Result r = run_small({src, dir + "/out.gpkg"}, {}, 20);
  expect_failure(r, 1, {"cannot open '" + src + "': not a regular file or directory (a FIFO)"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, TruncatedGeoJson) {
  const std::string dir = test_dir();
  const std::string whole = qtmv::test::read_file(geojson(dir + "/whole.geojson",
                                                          {R"({"type":"Point","coordinates":[1,2]})"}));
  const std::string src = write_text(dir + "/cut.geojson", whole.substr(0, whole.size() / 2));
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1, {"cannot open '" + src + "'", "GDAL:"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, LayerWithoutFeatures) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/none.gpkg", "GPKG", "nothing", "EPSG:4326", {});
  expect_failure(run_small({src, dir + "/out.gpkg"}), 1,
                 {"'" + src + "', layer 'nothing': no usable site (0 features read"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, MissingLayerListsTheLayers) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/one.gpkg", "GPKG", "cities", "EPSG:4326", points({"POINT (1 2)"}));
  expect_failure(run_small({"-l", "towns", src, dir + "/out.gpkg"}), 1,
                 {"'" + src + "' has no layer 'towns'; its layers: cities"}, dir + "/out.gpkg");
}

TEST(CatalogueFiles, OneLayerNamedTwiceInAnotherCaseIsRefused) {
  // GeoPackage layer names are case-insensitive: both -l found the same layer (twice the rows).
  const std::string dir = test_dir();
  expect_failure(run_small({"-l", "countries_110m", "-l", "COUNTRIES_110M", kCountries, dir + "/out.gpkg"}), 1,
                 {"'" + kCountries + "': -l 'countries_110m' and -l 'COUNTRIES_110M' name the same layer "
                  "'countries_110m': name it once"},
                 dir + "/out.gpkg");
}

TEST(CatalogueFiles, CorruptGeometryBlobSkipsThatFeatureByFid) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/blob.gpkg", "GPKG", "pts", "EPSG:4326",
                                       points({"POINT (1 2)", "POINT (3 4)", "POINT (60 -5)"}));
  qtmv::sites::test::corrupt_geometry(src, 2);
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "'" + src + "', layer 'pts', FID 2: unreadable feature (GDAL: ")) << r.err;
  const auto kept = regions(dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0].fid, 1);
  EXPECT_EQ(kept[1].fid, 3);
}

TEST(CatalogueFiles, SourceReplacedByItsOwnRegionsWithOverwrite) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/self.gpkg", "GPKG", "pts", "EPSG:4326",
                                       points({"POINT (1 2)", "POINT (100 -40)"}));
  const Result r = run_small({"-q", "-overwrite", "-layers", "regions", src, src});
  expect_success(r, src);
  EXPECT_EQ(regions(src).size(), 2u);
}

// ---------------------------------------------------------------------------------------------
// Geometries

// Many skipped features give 20 lines and a count, not a line each.
TEST(CatalogueGeometry, ManySkippedFeaturesAreCountedAfterTwentyLines) {
  const std::string dir = test_dir();
  std::vector<std::string> features(30, "null");
  features.push_back(R"({"type":"Point","coordinates":[3,4]})");
  const std::string src = geojson(dir + "/many_empty.geojson", features);
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "FID 19: empty geometry; feature skipped")) << r.err;
  EXPECT_FALSE(contains(r.err, "FID 20: empty geometry")) << r.err;
  EXPECT_TRUE(contains(r.err, "10 more skipped feature(s) not listed (30 in all)")) << r.err;
  EXPECT_TRUE(contains(r.err, "1 site read, 30 skipped")) << r.err;
}

TEST(CatalogueGeometry, NullAndEmptyGeometriesAreSkippedByFid) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/empty.geojson", {"null", R"({"type":"Point","coordinates":[]})",
                                                             R"({"type":"GeometryCollection","geometries":[]})",
                                                             R"({"type":"Point","coordinates":[3,4]})"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  for (int fid : {0, 1, 2}) {
    EXPECT_TRUE(contains(r.err, "layer 'empty', FID " + std::to_string(fid) + ": empty geometry; feature skipped"))
        << r.err;
  }
  EXPECT_TRUE(contains(r.err, "1 site read, 3 skipped")) << r.err;
  ASSERT_EQ(regions(dir + "/out.gpkg").size(), 1u);
  EXPECT_EQ(regions(dir + "/out.gpkg")[0].fid, 3);
}

TEST(CatalogueGeometry, NullGeometryUnderStrictFailsNamingTheFid) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/strict.geojson", {R"({"type":"Point","coordinates":[3,4]})", "null"});
  expect_failure(run_small({"-strict", src, dir + "/out.gpkg"}), 1,
                 {"'" + src + "', layer 'strict', FID 1: empty geometry (-strict)"}, dir + "/out.gpkg");
}

// One bad feature among good ones: skipped with its FID and reason, the others kept.
void expect_skipped(const std::string& src, const std::string& dst, const std::string& fid_and_reason,
                    std::size_t kept) {
  expect_kept(src, dst, fid_and_reason + "; feature skipped", kept);
}

TEST(CatalogueGeometry, InfiniteCoordinateFromGeoJson1e400) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/inf.geojson", {R"({"type":"Point","coordinates":[1e400,2]})",
                                                         R"({"type":"Point","coordinates":[3,4]})"});
  expect_skipped(src, dir + "/out.gpkg", "FID 0: NaN or infinite coordinate (inf, 2)", 1);
}

TEST(CatalogueGeometry, NaNCoordinate) {
  const std::string dir = test_dir();
  auto line = std::make_shared<OGRLineString>();
  line->addPoint(0, 0);
  line->addPoint(std::nan(""), 1);
  const std::string src = make_dataset(dir + "/nan.gpkg", "GPKG", "nan", "EPSG:4326",
                                       {{"POINT (5 5)", "good"}, {"", "nan", line}});
  expect_skipped(src, dir + "/out.gpkg", "layer 'nan', FID 2: NaN or infinite coordinate (nan, 1)", 1);
}

TEST(CatalogueGeometry, Latitude95) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/lat.geojson", {R"({"type":"Point","coordinates":[10,95]})",
                                                         R"({"type":"Point","coordinates":[3,4]})"});
  expect_skipped(src, dir + "/out.gpkg", "FID 0: latitude beyond +-90 at (10, 95)", 1);
}

TEST(CatalogueGeometry, Longitude720) {
  const std::string dir = test_dir();
  const std::string src = geojson(dir + "/lon.geojson", {R"({"type":"Point","coordinates":[720,5]})",
                                                         R"({"type":"Point","coordinates":[3,4]})"});
  expect_skipped(src, dir + "/out.gpkg", "FID 0: coordinate (720, 5) beyond +-540 degrees of its CRS", 1);
}

TEST(CatalogueGeometry, UnsupportedTypesAreSkippedByFid) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/types.csv", {"POINT (3 4)", "TIN (((0 0 0,0 1 0,1 0 0,0 0 0)))",
                                                       "POLYHEDRALSURFACE Z (((0 0 0,0 1 0,1 1 0,0 0 0)))"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "FID 2: unsupported geometry type 3D TIN; feature skipped")) << r.err;
  EXPECT_TRUE(contains(r.err, "FID 3: unsupported geometry type 3D PolyhedralSurface; feature skipped")) << r.err;
  EXPECT_EQ(regions(dir + "/out.gpkg").size(), 1u);
}

// The cells of a polygon site alone with a far point (its region: the polygon and what is nearer
// to it than to the point).
GIntBig polygon_cells(const std::string& dir, const std::string& name, const std::string& wkt) {
  const std::string src = wkt_csv(dir + "/" + name + ".csv", {wkt, "POINT (-150 -60)"});
  const auto r = regions_of(src, dir + "/" + name + ".gpkg");
  return r.size() == 2 ? r[0].cells : -1;
}

TEST(CatalogueGeometry, UnclosedRingIsClosed) {
  const std::string dir = test_dir();
  const GIntBig closed = polygon_cells(dir, "closed", "POLYGON ((0 0,10 0,10 10,0 10,0 0))");
  EXPECT_GT(closed, 0);
  EXPECT_EQ(polygon_cells(dir, "unclosed", "POLYGON ((0 0,10 0,10 10,0 10))"), closed);
  // ... and says so.
  const std::string src = dir + "/unclosed.csv";  // written by polygon_cells
  expect_kept(src, dir + "/again.gpkg", "'" + src + "', layer 'unclosed', FID 1: invalid polygon (Ring not closed at (0, 10))", 2);
}

TEST(CatalogueGeometry, DuplicateVerticesChangeNothing) {
  const std::string dir = test_dir();
  const GIntBig plain = polygon_cells(dir, "plain", "POLYGON ((0 0,10 0,10 10,0 10,0 0))");
  EXPECT_GT(plain, 0);
  EXPECT_EQ(polygon_cells(dir, "repeated", "POLYGON ((0 0,0 0,10 0,10 0,10 0,10 10,0 10,0 10,0 0,0 0))"), plain);
}

TEST(CatalogueGeometry, BowTieZeroAreaAndTwoPointRingsAreKept) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/odd.csv", {"POLYGON ((20 0,30 10,30 0,20 10,20 0))",
                                                     "POLYGON ((60 0,70 0,65 0,60 0))", "POLYGON ((100 0,110 0))",
                                                     "POINT (-150 -60)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_FALSE(contains(r.err, "feature skipped")) << r.err;
  // Kept, but no longer silently: each is named with GEOS's reason.
  const std::string where = "'" + src + "', layer 'odd', FID ";
  EXPECT_TRUE(contains(r.err, where + "1: invalid polygon (Self-intersection at (25, 5))")) << r.err;
  EXPECT_TRUE(contains(r.err, where + "2: invalid polygon (Self-intersection at (65, 0))")) << r.err;
  EXPECT_TRUE(contains(r.err, where + "3: invalid polygon (Too few points in ring at (100, 0))")) << r.err;
  EXPECT_FALSE(contains(r.err, where + "4: invalid")) << r.err;
  const auto kept = regions(dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 4u);
  for (const Region& region : kept) EXPECT_GT(region.cells, 0) << "FID " << region.fid;
}

TEST(CatalogueGeometry, PolygonLargerThanAHemisphere) {
  const std::string dir = test_dir();
  // 340 by 160 degrees: 93% of the sphere, the point outside it. Its edges are all shorter than
  // 180 degrees of longitude: one from -170 to 170 would be read the short way, across +-180
  // (-wrap auto), and the polygon would be the 20 degree band there.
  const std::string big = "POLYGON ((-170 -80,-85 -80,0 -80,85 -80,170 -80,170 80,85 80,0 80,-85 80,-170 80,-170 -80))";
  const auto kept = regions_of(wkt_csv(dir + "/big.csv", {big, "POINT (175 0)"}), dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_GT(kept[0].area_fraction, 0.92);
  EXPECT_GT(kept[1].cells, 0);
  // The same polygon in four vertices, read as flat lon/lat.
  const auto flat = regions_of(wkt_csv(dir + "/flat.csv", {"POLYGON ((-170 -80,170 -80,170 80,-170 80,-170 -80))",
                                                           "POINT (175 0)"}),
                               dir + "/flat.gpkg", {"-wrap", "none"});
  ASSERT_EQ(flat.size(), 2u);
  EXPECT_EQ(flat[0].cells, kept[0].cells);
}

TEST(CatalogueGeometry, PolygonAroundAPoleHoldsThePole) {
  const std::string dir = test_dir();
  // A ring along latitude 80 that winds round the north pole, and a point on the pole: the
  // polygon's interior holds the pole, so the point gets no cell and says so.
  const std::string src = wkt_csv(dir + "/cap.csv", {"POLYGON ((0 80,90 80,180 80,-90 80,0 80))", "POINT (0 90)",
                                                     "POINT (0 -30)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "1 site(s) got no cell of their own at level 4 (FIDs 2)")) << r.err;
  const auto kept = regions(dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_GT(kept[0].area_fraction, (1 - std::sin(80 * M_PI / 180)) / 2);  // at least the cap
  EXPECT_EQ(kept[1].cells, 0);
}

// Band 1 (site FID) and band 3 (distance, metres) of a lon/lat raster at (lon, lat) (degrees).
std::pair<double, double> fid_and_distance_at(const std::string& tif, double lon, double lat) {
  const auto ds = qtmv::test::open_dataset(tif, GDAL_OF_RASTER);
  if (!ds) return {-1, -1};
  double gt[6];
  ds->GetGeoTransform(gt);
  const int x = static_cast<int>((lon - gt[0]) / gt[1]), y = static_cast<int>((lat - gt[3]) / gt[5]);
  double fid = -1, metres = -1;
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, x, y, 1, 1, &fid, 1, 1, GDT_Float64, 0, 0) != CE_None ||
      ds->GetRasterBand(3)->RasterIO(GF_Read, x, y, 1, 1, &metres, 1, 1, GDT_Float64, 0, 0) != CE_None) {
    return {-1, -1};
  }
  return {fid, metres};
}

TEST(CatalogueGeometry, PolarCapCutAtTheAntimeridianIsReadAsWritten) {
  // Issue 12's cap, as cut data sets write it: the edge from (-180, 86) to (180, 86) is the whole
  // parallel and the one from (180, 90) to (-180, 90) runs along the pole. Read "the short way"
  // it had become a line along +-180, and the cell at 88N 45E had got it at 208 km.
  const std::string dir = test_dir();
  const std::string src =
      geojson(dir + "/cap.geojson", {R"({"type":"Polygon","coordinates":[[[-180,86],[180,86],[180,90],[-180,90],[-180,86]]]})",
                                     R"({"type":"Point","coordinates":[45,60]})"});
  const Result r = run({"-level", "8", "-device", "cpu", "-raster", "lonlat", "-tr", "1", "1", src, dir + "/cap.tif"});
  expect_success(r, dir + "/cap.tif");
  EXPECT_FALSE(contains(r.err, "short way")) << r.err;
  for (double lon : {-179.5, -90.5, 45.5, 179.5}) {
    const auto inside = fid_and_distance_at(dir + "/cap.tif", lon, 88.5);
    EXPECT_EQ(inside.first, 0) << lon;
    EXPECT_EQ(inside.second, 0) << lon;
    // Just outside: about a degree from the parallel (the pixel's cell centre, within a cell).
    const auto outside = fid_and_distance_at(dir + "/cap.tif", lon, 84.5);
    EXPECT_EQ(outside.first, 0) << lon;
    EXPECT_NEAR(outside.second, 1.5 * 111195, 0.4 * 111195) << lon;
  }
}

TEST(CatalogueGeometry, EdgesJoinedTheShortWayAreNamedInAWarning) {
  // Uncut data (a ring stepping across +-180, as world-atlas's Fiji and Russia do) is joined the
  // short way by -wrap auto: said once for the layer, with the features' FIDs.
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/uncut.csv", {"POINT (0 0)", "POLYGON ((170 -20,-170 -20,-170 -10,170 -10,170 -20))",
                                                       "LINESTRING (175 40,-175 41)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "2 feature(s) have edges more than 180 degrees of longitude long joined the short way "
                              "across +-180 (-wrap auto; -wrap none reads them as written) (FIDs 2, 3)"))
      << r.err;
  // With -wrap none they are read as written, and nothing is said.
  const Result flat = run_small({"-layers", "regions", "-wrap", "none", src, dir + "/flat.gpkg"});
  expect_success(flat, dir + "/flat.gpkg");
  EXPECT_FALSE(contains(flat.err, "short way")) << flat.err;
}

TEST(CatalogueGeometry, ZAndMCoordinatesAreDropped) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/zm.csv", {"POINT ZM (1 2 3 4)", "LINESTRING Z (60 5 1,70 6 2)",
                                                    "POLYGON M ((-60 -10 1,-50 -10 2,-50 0 3,-60 -10 1))"});
  const auto kept = regions_of(src, dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 3u);
  for (const Region& region : kept) EXPECT_GT(region.cells, 0) << "FID " << region.fid;
}

TEST(CatalogueGeometry, CurvedGeometriesAreLinearised) {
  const std::string dir = test_dir();
  const std::string src =
      wkt_csv(dir + "/curves.csv", {"CIRCULARSTRING (0 -20,5 -15,10 -20)",
                                    "CURVEPOLYGON (CIRCULARSTRING (60 -40,70 -40,70 -30,60 -30,60 -40))",
                                    "COMPOUNDCURVE ((100 10,110 10),CIRCULARSTRING (110 10,115 15,120 10))",
                                    "MULTISURFACE (CURVEPOLYGON (CIRCULARSTRING (-90 30,-85 35,-80 30,-85 25,-90 30)))"});
  const auto kept = regions_of(src, dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 4u);
  for (const Region& region : kept) EXPECT_GT(region.cells, 0) << "FID " << region.fid;
}

TEST(CatalogueGeometry, GeometryCollectionNestingAllTypesIsOneSite) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(
      dir + "/gc.csv",
      {"GEOMETRYCOLLECTION (POINT (1 -50),LINESTRING (2 -50,3 -51),POLYGON ((5 -50,6 -50,6 -49,5 -50)),"
       "MULTIPOINT ((7 -50)),MULTILINESTRING ((8 -50,9 -50)),MULTIPOLYGON (((10 -50,11 -50,11 -49,10 -50))),"
       "GEOMETRYCOLLECTION (POINT (12 -50),CIRCULARSTRING (13 -50,14 -49,15 -50),POINT EMPTY))",
       "POINT (100 40)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "2 sites read, 0 skipped")) << r.err;
  const auto kept = regions(dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_GT(kept[0].cells, 0);
}

TEST(CatalogueGeometry, TenThousandIdenticalPoints) {
  const std::string dir = test_dir();
  std::string text = "lon,lat\n";
  for (int k = 0; k < 10000; ++k) text += "5,5\n";
  text += "-120,-30\n";
  const std::string src = write_text(dir + "/same.csv", text);
  const auto start = std::chrono::steady_clock::now();
  const Result r = run_small({"-layers", "regions", "-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat",
                              src, dir + "/out.gpkg"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
  expect_success(r, dir + "/out.gpkg");
  // Ties go to the site read first; the others are named (the first ten) and keep their rows.
  EXPECT_TRUE(contains(r.err, "9999 site(s) got no cell of their own at level 4 (FIDs 2, 3, 4")) << r.err;
  const auto kept = regions(dir + "/out.gpkg");
  ASSERT_EQ(kept.size(), 10001u);
  EXPECT_GT(kept[0].cells, 0);
  EXPECT_EQ(kept[1].cells, 0);
  EXPECT_GT(kept[10000].cells, 0);
}

// ---------------------------------------------------------------------------------------------
// Invalid polygons: each named by file, layer, FID, GEOS's reason and place; read by
// one rule (even-odd over all rings, parts united, rings traced); -strict fails; -makevalid
// repairs and says what the polygon became.

// The line of `text` that holds `part` (empty when none does).
std::string line_with(const std::string& text, const std::string& part) {
  const std::size_t at = text.find(part);
  if (at == std::string::npos) return "";
  const std::size_t begin = text.rfind('\n', at) == std::string::npos ? 0 : text.rfind('\n', at) + 1;
  const std::size_t end = text.find('\n', at);
  return text.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
}

bool ends_with(const std::string& text, const std::string& tail) {
  return text.size() >= tail.size() && text.compare(text.size() - tail.size(), tail.size(), tail) == 0;
}

struct CellLabel {
  GIntBig site_fid = -1;
  double distance_m = -1;
};

// The label of the cell holding (lon, lat) in the cells layer of `dst`.
CellLabel cell_at(const std::string& dst, double lon, double lat, int level) {
  CellLabel out;
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  OGRLayer* cells = ds ? ds->GetLayerByName("cells") : nullptr;
  if (!cells) return out;
  const std::string filter = "code = " + std::to_string(qtmv::grid::lonlat_to_code(lon, lat, level));
  cells->SetAttributeFilter(filter.c_str());
  for (auto& f : *cells) out = {f->GetFieldAsInteger64("site_fid"), f->GetFieldAsDouble("distance_m")};
  return out;
}

// The hole of the issue's example lies outside its shell; the point is far away.
const std::string kOutsideHole = "POLYGON ((0 0,10 0,10 10,0 10,0 0),(20 20,25 20,25 25,20 25,20 20))";

TEST(CataloguePolygons, HoleOutsideItsShellIsNamedAndReadAsAnIsland) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/hole.csv", {kOutsideHole, "POINT (-100 -40)"});
  const std::string dst = dir + "/out.gpkg";
  const Result r = run({"-level", "6", "-device", "cpu", "-layers", "cells,regions", src, dst});
  expect_success(r, dst);
  EXPECT_TRUE(contains(r.err, "warning: '" + src + "', layer 'hole', FID 1: invalid polygon (Hole lies outside shell "
                              "at (20, 20)); read by even-odd over all rings (-makevalid repairs it)"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "1 invalid polygon(s) (read by even-odd)")) << r.err;
  EXPECT_TRUE(contains(r.err, "2 sites read, 0 skipped, 1 with an invalid polygon; level 6")) << r.err;
  // Even-odd: the "hole" is an island of the polygon.
  const CellLabel island = cell_at(dst, 22.5, 22.5, 6);
  EXPECT_EQ(island.site_fid, 1);
  EXPECT_EQ(island.distance_m, 0.0);
  EXPECT_EQ(cell_at(dst, 5, 5, 6).distance_m, 0.0);
}

TEST(CataloguePolygons, InvalidPolygonUnderStrictFailsNamingTheFidAndReason) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/hole.csv", {"POINT (-100 -40)", kOutsideHole});
  const std::string dst = dir + "/out.gpkg";
  expect_failure(run_small({"-strict", src, dst}), 1,
                 {"'" + src + "', layer 'hole', FID 2: invalid polygon (Hole lies outside shell at (20, 20)) "
                  "(-strict; -makevalid repairs it)"},
                 dst);
}

TEST(CataloguePolygons, MakeValidRepairsAndSaysWhatThePolygonBecame) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/hole.csv", {kOutsideHole, "POINT (-100 -40)"});
  const std::string dst = dir + "/out.gpkg";
  // -strict too: a repaired polygon is no error.
  const Result r = run({"-level", "6", "-device", "cpu", "-makevalid", "-strict", "-layers", "cells,regions", src, dst});
  expect_success(r, dst);
  EXPECT_TRUE(contains(r.err, "warning: '" + src + "', layer 'hole', FID 1: invalid polygon (Hole lies outside shell "
                              "at (20, 20)); repaired by -makevalid: Polygon of 2 rings became MultiPolygon of 2 "
                              "polygons"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "1 invalid polygon(s) (1 repaired by -makevalid)")) << r.err;
  EXPECT_TRUE(contains(r.err, "2 sites read, 0 skipped, 1 with an invalid polygon (1 repaired); level 6")) << r.err;
  EXPECT_FALSE(contains(r.err, "even-odd")) << r.err;
  // GEOS makes the outside hole a polygon of its own (as ogr2ogr -makevalid): the same cells.
  EXPECT_EQ(cell_at(dst, 22.5, 22.5, 6).site_fid, 1);
  EXPECT_EQ(cell_at(dst, 22.5, 22.5, 6).distance_m, 0.0);
  ASSERT_EQ(regions(dst).size(), 2u);
}

// The kinds of invalid polygon, each at its own longitude, with the reason GEOS (or the reader,
// for what GEOS cannot take) gives. Each is read by the rule and named; -makevalid gives the
// same cells for each, as the man page says.
struct InvalidCase {
  const char* name;
  std::string wkt;
  std::string reason;
  std::string became;  // -makevalid's result
};

std::vector<InvalidCase> invalid_cases() {
  return {
      {"bow-tie", "POLYGON ((0 0,10 10,10 0,0 10,0 0))", "Self-intersection at (5, 5)", "MultiPolygon of 2 polygons"},
      {"zero-area ring", "POLYGON ((30 0,40 0,35 0,30 0))", "Self-intersection at (35, 0)",
       "MultiLineString of 2 parts"},
      {"ring of two points", "POLYGON ((60 0,70 0))", "Too few points in ring at (60, 0)", "LineString"},
      {"ring of three points", "POLYGON ((90 0,100 0,90 0))", "Too few points in ring at (90, 0)", "LineString"},
      {"unclosed ring", "POLYGON ((120 0,130 0,130 10,120 10))", "Ring not closed at (120, 10)", "Polygon of 1 ring"},
      {"spike", "POLYGON ((150 0,160 0,160 10,155 10,155 20,155 10,150 10,150 0))",
       "Ring Self-intersection at (155, 10)", "GeometryCollection (Polygon of 1 ring, LineString)"},
      {"nested holes", "POLYGON ((-60 -10,-40 -10,-40 10,-60 10,-60 -10),(-58 -8,-42 -8,-42 8,-58 8,-58 -8),"
                       "(-55 -5,-45 -5,-45 5,-55 5,-55 -5))",
       "Holes are nested at (-55, -5)", "MultiPolygon of 2 polygons"},
      {"overlapping parts", "MULTIPOLYGON (((-100 0,-90 0,-90 10,-100 10,-100 0)),((-95 5,-85 5,-85 15,-95 15,-95 5)))",
       "Self-intersection at (-90, 5)", "MultiPolygon of 2 polygons"},
      {"hole touching its shell along an edge", "POLYGON ((-150 0,-140 0,-140 10,-150 10,-150 0),(-150 0,-145 0,-145 5,-150 0))",
       "Self-intersection at (-150, 0)", "GeometryCollection (Polygon of 1 ring, LineString)"},
      {"ring collapsed to a point", "POLYGON ((-120 -30,-120 -30,-120 -30,-120 -30))",
       "Too few points in geometry component at (-120, -30)", "Point"},
  };
}

// The cells at distance 0 from each site (inside its polygons or on its lines), by FID.
std::map<GIntBig, std::set<GIntBig>> cells_on_sites(const std::string& dst) {
  std::map<GIntBig, std::set<GIntBig>> out;
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  OGRLayer* cells = ds ? ds->GetLayerByName("cells") : nullptr;
  if (!cells) return out;
  cells->SetAttributeFilter("distance_m = 0");
  for (auto& f : *cells) out[f->GetFieldAsInteger64("site_fid")].insert(f->GetFieldAsInteger64("code"));
  return out;
}

TEST(CataloguePolygons, EveryKindIsNamedByFidAndReasonAndReadByTheDocumentedRule) {
  const std::string dir = test_dir();
  const std::vector<InvalidCase> cases = invalid_cases();
  std::vector<std::string> wkts;
  for (const InvalidCase& c : cases) wkts.push_back(c.wkt);
  wkts.push_back("POINT (-170 -60)");
  const std::string src = wkt_csv(dir + "/kinds.csv", wkts);
  const std::string where = "'" + src + "', layer 'kinds', FID ";
  const std::size_t n = cases.size();

  const std::vector<std::string> options{"-level", "6", "-device", "cpu", "-layers", "cells,regions"};
  const Result r = run(concat(options, {src, dir + "/plain.gpkg"}));
  expect_success(r, dir + "/plain.gpkg");
  const Result m = run(concat(concat(options, {"-makevalid"}), {src, dir + "/valid.gpkg"}));
  expect_success(m, dir + "/valid.gpkg");
  for (std::size_t k = 0; k < n; ++k) {
    const InvalidCase& c = cases[k];
    const std::string what = where + std::to_string(k + 1) + ": invalid polygon (" + c.reason + ")";
    EXPECT_TRUE(contains(r.err, what + "; read by even-odd over all rings (-makevalid repairs it)")) << c.name << ": " << r.err;
    const std::string repaired = line_with(m.err, what + "; repaired by -makevalid: ");
    EXPECT_TRUE(ends_with(repaired, " became " + c.became)) << c.name << ": " << m.err;
  }
  EXPECT_TRUE(contains(r.err, std::to_string(n) + " invalid polygon(s) (read by even-odd)")) << r.err;
  EXPECT_FALSE(contains(r.err, "feature skipped")) << r.err;
  EXPECT_FALSE(contains(m.err, "feature skipped")) << m.err;

  // The rule: the bow-tie is both its triangles, the hole in the hole an island, overlapping
  // parts their union; a zero-area ring or a spike only the cells along it.
  auto label = [&](const std::string& dst, double lon, double lat) { return cell_at(dst, lon, lat, 6); };
  const std::string plain = dir + "/plain.gpkg", valid = dir + "/valid.gpkg";
  EXPECT_EQ(label(plain, 8, 5).site_fid, 1);            // bow-tie, right triangle
  EXPECT_EQ(label(plain, 8, 5).distance_m, 0.0);
  EXPECT_EQ(label(plain, 2, 5).distance_m, 0.0);        // bow-tie, left triangle
  EXPECT_GT(label(plain, 5, 1.5).distance_m, 0.0);      // between them, outside
  EXPECT_EQ(label(plain, 155, 15).site_fid, 6);         // along the spike
  EXPECT_LT(label(plain, 155, 15).distance_m, 1.2e5);   // its centre within a cell of the line
  EXPECT_EQ(cells_on_sites(plain).count(2), 0u);        // the zero-area ring fills nothing
  EXPECT_EQ(label(plain, -50, 0).distance_m, 0.0);      // the island in the hole
  EXPECT_GT(label(plain, -50.5, 6.5).distance_m, 0.0);  // the hole around it
  EXPECT_EQ(label(plain, -92.5, 7.5).distance_m, 0.0);  // where the parts overlap
  EXPECT_EQ(label(plain, -92.5, 7.5).site_fid, 8);

  // -makevalid (GEOS's linework method, as ogr2ogr) agrees, except that it reads overlapping
  // parts even-odd too (their overlap becomes a hole) and fills a hole that touches its shell
  // along an edge (it keeps the hole's ring as a line).
  auto before = cells_on_sites(plain), after = cells_on_sites(valid);
  for (std::size_t k = 0; k < n; ++k) {
    const GIntBig fid = static_cast<GIntBig>(k + 1);
    if (cases[k].name == std::string("overlapping parts") || cases[k].name == std::string("hole touching its shell along an edge")) {
      EXPECT_NE(after[fid], before[fid]) << cases[k].name;
    } else {
      EXPECT_EQ(after[fid], before[fid]) << cases[k].name;
    }
  }
  EXPECT_GT(label(valid, -92.5, 7.5).distance_m, 0.0);
}

TEST(CataloguePolygons, ValidOddPolygonsGetNoWarning) {
  const std::string dir = test_dir();
  // Duplicate consecutive vertices, a hole touching its shell at a point, a MultiPolygon whose
  // parts touch at a corner: valid (OGC, GEOS), so nothing to say.
  const std::string src = wkt_csv(
      dir + "/fine.csv", {"POLYGON ((0 0,0 0,10 0,10 0,10 10,0 10,0 10,0 0))",
                          "POLYGON ((30 0,40 0,40 10,30 10,30 0),(30 0,35 5,38 2,30 0))",
                          "MULTIPOLYGON (((60 0,70 0,70 10,60 10,60 0)),((70 10,80 10,80 20,70 20,70 10)))"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_FALSE(contains(r.err, "invalid polygon")) << r.err;
}

TEST(CataloguePolygons, ManyInvalidPolygonsAreListedUpToTwentyThenCounted) {
  const std::string dir = test_dir();
  std::vector<std::string> wkts;
  for (int k = 0; k < 25; ++k) {
    const int x = -175 + 14 * k;
    wkts.push_back("POLYGON ((" + std::to_string(x) + " 0," + std::to_string(x + 10) + " 10," + std::to_string(x + 10) +
                   " 0," + std::to_string(x) + " 10," + std::to_string(x) + " 0))");
  }
  const std::string src = wkt_csv(dir + "/ties.csv", wkts);
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  std::size_t listed = 0;
  for (std::size_t at = r.err.find("invalid polygon (Self"); at != std::string::npos;
       at = r.err.find("invalid polygon (Self", at + 1)) {
    ++listed;
  }
  EXPECT_EQ(listed, 20u) << r.err;
  EXPECT_TRUE(contains(r.err, "FID 20: invalid polygon")) << r.err;
  EXPECT_FALSE(contains(r.err, "FID 21: invalid polygon")) << r.err;
  EXPECT_TRUE(contains(r.err, "'" + src + "', layer 'ties': 5 more invalid polygon(s) not listed (25 in all)")) << r.err;
  EXPECT_TRUE(contains(r.err, "25 invalid polygon(s) (read by even-odd)")) << r.err;
}

TEST(CataloguePolygons, RingAcrossTheAntimeridianIsNotCalledInvalid) {
  const std::string dir = test_dir();
  // Simple when read across +-180 (-wrap auto), self-intersecting in flat lon/lat: as uncut
  // TopoJSON (world-atlas) gives Fiji and Russia.
  const std::string src =
      wkt_csv(dir + "/fiji.csv", {"POLYGON ((170 0,-170 0,-170 10,-175 10,175 5,170 10,170 0))", "POINT (0 0)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/auto.gpkg"});
  expect_success(r, dir + "/auto.gpkg");
  EXPECT_FALSE(contains(r.err, "invalid polygon")) << r.err;
  // Read flat (-wrap none), it is what GEOS says it is.
  const Result flat = run_small({"-wrap", "none", "-layers", "regions", src, dir + "/flat.gpkg"});
  expect_success(flat, dir + "/flat.gpkg");
  EXPECT_TRUE(contains(flat.err, "FID 1: invalid polygon (Self-intersection at (")) << flat.err;
}

TEST(CataloguePolygons, ProjectedPolygonIsCheckedInItsOwnCrs) {
  const std::string dir = test_dir();
  // A bow-tie in EPSG:3857 metres: the place is given in the source's coordinates.
  const std::string src = make_dataset(dir + "/merc.gpkg", "GPKG", "merc", "EPSG:3857",
                                       points({"POLYGON ((0 0,1000000 1000000,1000000 0,0 1000000,0 0))",
                                               "POINT (-10000000 -5000000)"}));
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "'" + src + "', layer 'merc', FID 1: invalid polygon (Self-intersection at (500000, 500000))"))
      << r.err;
}

// ---------------------------------------------------------------------------------------------
// CRS

TEST(CatalogueCrs, NoCrsIsTakenAsWgs84WithAWarning) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/nocrs.csv", {"POINT (3 4)"});
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"});
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "warning: '" + src + "', layer 'nocrs': the layer has no CRS; its coordinates are "
                              "taken as EPSG:4326"))
      << r.err;
}

TEST(CatalogueCrs, WebMercatorNear1e20NeitherHangsNorStops) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/huge.gpkg", "GPKG", "huge", "EPSG:3857", points({
      "POINT (1e20 -1e20)", "POINT (1000000 2000000)", "POINT (-1e20 1e20)"}));
  const Result r = run_small({"-layers", "regions", src, dir + "/out.gpkg"}, {}, 30);
  expect_success(r, dir + "/out.gpkg");
  EXPECT_TRUE(contains(r.err, "FID 1: coordinate (1e+20, -1e+20) beyond +-1e8 metres of its CRS; feature skipped"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "FID 3: coordinate (-1e+20, 1e+20) beyond +-1e8 metres")) << r.err;
  ASSERT_EQ(regions(dir + "/out.gpkg").size(), 1u);
}

TEST(CatalogueCrs, OnlyHugeCoordinatesIsNoUsableSite) {
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/huge.gpkg", "GPKG", "huge", "EPSG:3857", points({"POINT (1e20 0)"}));
  expect_failure(run_small({src, dir + "/out.gpkg"}, {}, 30), 1,
                 {"'" + src + "', layer 'huge': no usable site (1 features read, 1 skipped)"}, dir + "/out.gpkg");
}

TEST(CatalogueCrs, BadSourceSrs) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/a.csv", {"POINT (3 4)"});
  expect_failure(run_small({"-s_srs", "EPSG:999999", src, dir + "/out.gpkg"}), 1,
                 {"-s_srs: cannot read 'EPSG:999999'"}, dir + "/out.gpkg");
}

TEST(CatalogueCrs, CrsWithoutATransformationToWgs84) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/local.csv", {"POINT (3 4)"});
  expect_failure(run_small({"-s_srs", R"(LOCAL_CS["site grid",UNIT["metre",1]])", src, dir + "/out.gpkg"}), 1,
                 {"'" + src + "', layer 'local': no transformation from its CRS (site grid) to WGS84"},
                 dir + "/out.gpkg");
}

// ---------------------------------------------------------------------------------------------
// Options (usage errors exit 2 with the usage; nothing is read or written)

TEST(CatalogueOptions, BadLevels) {
  const std::string dir = test_dir();
  for (const char* level : {"-1", "25", "nine", "9.5", ""}) {
    expect_failure(run({"-level", level, "in.csv", dir + "/out.gpkg"}), 2,
                   {std::string("-level: '") + level + "' is not a level from 0 to 24"}, dir + "/out.gpkg");
  }
}

TEST(CatalogueOptions, UnknownOption) {
  const std::string dir = test_dir();
  expect_failure(run({"-levle", "5", "in.csv", dir + "/out.gpkg"}), 2, {"unknown option '-levle'"},
                 dir + "/out.gpkg");
}

TEST(CatalogueOptions, OptionWithoutItsValue) {
  const std::string dir = test_dir();
  expect_failure(run({"in.csv", dir + "/out.gpkg", "-l"}), 2, {"option '-l' needs a value"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, MissingDestination) {
  const std::string dir = test_dir();
  expect_failure(run({"-level", "3", kCountries}), 2, {"DST_DATASOURCE is missing"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, UnknownFormat) {
  const std::string dir = test_dir();
  expect_failure(run_small({"-of", "NoSuchDriver", kCountries, dir + "/out.gpkg"}), 1,
                 {"-of NoSuchDriver: no such GDAL driver"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, UnguessableFormat) {
  const std::string dir = test_dir();
  expect_failure(run_small({kCountries, dir + "/out.xyz123"}), 1,
                 {"cannot tell the output format from '" + dir + "/out.xyz123'", "-of FORMAT"}, dir + "/out.xyz123");
}

TEST(CatalogueOptions, DriverThatCannotWriteOurData) {
  const std::string dir = test_dir();
  // WMS lists CreateCopy, but copies only WMS datasets: refused when the copy is made.
  expect_failure(run_small({"-of", "WMS", "-l", "countries_110m", kCountries, dir + "/out.xml"}), 1,
                 {dir + "/out.xml", "WMS"}, dir + "/out.xml");
}

TEST(CatalogueOptions, SqlWithWhereOrLayerConflict) {
  const std::string dir = test_dir();
  expect_failure(run({"-sql", "SELECT * FROM countries_110m", "-where", "pop_est > 1", kCountries, dir + "/out.gpkg"}),
                 2, {"-sql and -where exclude each other"}, dir + "/out.gpkg");
  expect_failure(run({"-sql", "SELECT * FROM countries_110m", "-l", "countries_110m", kCountries, dir + "/out.gpkg"}),
                 2, {"-sql and -l exclude each other"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, BadSqlAndBadWhere) {
  const std::string dir = test_dir();
  expect_failure(run_small({"-sql", "SELEC nonsense", kCountries, dir + "/out.gpkg"}), 1,
                 {"'" + kCountries + "': -sql failed: SELEC nonsense (GDAL: "}, dir + "/out.gpkg");
  expect_failure(run_small({"-where", "no_such_field = 1", "-l", "countries_110m", kCountries, dir + "/out.gpkg"}), 1,
                 {"layer 'countries_110m': bad -where: no_such_field = 1"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, SqlFileMissing) {
  const std::string dir = test_dir();
  expect_failure(run({"-sql", "@" + dir + "/none.sql", kCountries, dir + "/out.gpkg"}), 2,
                 {"-sql: cannot read '" + dir + "/none.sql'"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, SqlFromADeviceIsRefused) {
  const std::string dir = test_dir();
  // Read to its end, /dev/zero would fill the memory.
  expect_failure(run({"-sql", "@/dev/zero", kCountries, dir + "/out.gpkg"}, {}, 20), 2,
                 {"-sql: cannot read '/dev/zero': not a regular file"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, UnknownOpenOptionIsReported) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/a.csv", {"POINT (3 4)"});
  // Was silent: GDAL's warning was dropped with the open's other messages.
  expect_kept(src, dir + "/out.gpkg", "'" + src + "': GDAL: driver CSV does not support open option NO_SUCH_OPTION", 1,
              {"-oo", "NO_SUCH_OPTION=1"});
}

TEST(CatalogueOptions, CudaWithoutAGpuFailsBeforeReading) {
  if (qtmv::label::cuda_device_count() > 0) GTEST_SKIP() << "this host has a CUDA GPU";
  const std::string dir = test_dir();
  // The source does not exist: the device is checked first.
  expect_failure(run({"-device", "cuda", dir + "/missing.gpkg", dir + "/out.gpkg"}), 1,
                 {"-device cuda: no usable CUDA GPU found; use -device cpu or auto"}, dir + "/out.gpkg");
}

TEST(CatalogueOptions, BadThreadsAndDevice) {
  const std::string dir = test_dir();
  expect_failure(run({"-threads", "0", "in.csv", dir + "/out.gpkg"}), 2, {"-threads: '0' is not a number of threads"},
                 dir + "/out.gpkg");
  expect_failure(run({"-device", "gpu", "in.csv", dir + "/out.gpkg"}), 2, {"-device: 'gpu' is not one of"},
                 dir + "/out.gpkg");
}

// ---------------------------------------------------------------------------------------------
// Output

TEST(CatalogueOutput, ExistingDestinationWithoutOverwriteIsUntouched) {
  const std::string dir = test_dir();
  const std::string dst = write_text(dir + "/out.gpkg", "precious");
  const Result r = run_small({kCountries, dst});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "'" + dst + "' exists: use -overwrite to replace it")) << r.err;
  EXPECT_EQ(qtmv::test::read_file(dst), "precious");
  EXPECT_TRUE(hidden_entries(dir).empty());
}

TEST(CatalogueOutput, UnwritableDirectory) {
  const std::string dir = test_dir();
  const std::string locked = dir + "/locked";
  fs::create_directory(locked);
  chmod(locked.c_str(), 0555);
  expect_failure(run_small({"-l", "countries_110m", kCountries, locked + "/out.gpkg"}, ChildSetup{-1, true}), 1,
                 {"cannot write '" + locked + "/out.gpkg': cannot create a file in '" + locked + "'"},
                 locked + "/out.gpkg");
}

TEST(CatalogueOutput, MissingDirectory) {
  const std::string dir = test_dir();
  expect_failure(run_small({kCountries, dir + "/no/such/out.gpkg"}), 1,
                 {"cannot write '" + dir + "/no/such/out.gpkg': no directory '" + dir + "/no/such'"},
                 dir + "/no/such/out.gpkg");
}

TEST(CatalogueOutput, OverwriteOntoADirectoryLeavesIt) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.gpkg";
  fs::create_directory(dst);
  write_text(dst + "/keep.txt", "kept");
  const Result r = run_small({"-overwrite", "-layers", "regions", "-l", "countries_110m", kCountries, dst});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_TRUE(contains(r.err, "cannot write '" + dst + "': renaming into '" + dst + "': Is a directory")) << r.err;
  EXPECT_EQ(qtmv::test::read_file(dst + "/keep.txt"), "kept");
  EXPECT_TRUE(hidden_entries(dir).empty());
}

TEST(CatalogueOutput, OverwriteOfADirectoryOfLayersKeepsTheUsersOtherFiles) {
  // ogr2ogr -overwrite into a directory replaces the layers it writes and nothing else.
  const std::string dir = test_dir();
  const std::string dst = dir + "/proj";
  fs::create_directory(dst);
  write_text(dst + "/notes.txt", "my notes");
  write_text(dst + "/survey.geojson", R"({"type":"FeatureCollection","features":[]})");
  write_text(dst + "/regions.csv", "old");
  const Result r = run_small({"-q", "-of", "CSV", "-overwrite", "-layers", "regions", "-l", "countries_110m",
                              kCountries, dst});
  expect_success(r, dst);
  EXPECT_EQ(qtmv::test::read_file(dst + "/notes.txt"), "my notes");
  EXPECT_EQ(qtmv::test::read_file(dst + "/survey.geojson"), R"({"type":"FeatureCollection","features":[]})");
  EXPECT_TRUE(contains(qtmv::test::read_file(dst + "/regions.csv"), "site_fid"));
  EXPECT_TRUE(hidden_entries(dst).empty());
}

TEST(CatalogueOutput, OverwriteOfAGeoPackageHeldOpenInWalModeGivesAWholeNewFile) {
  // QGIS holds a GeoPackage open in WAL mode: its -wal and -shm must not stay beside the new file.
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.gpkg";
  expect_success(run_small({"-q", "-layers", "regions", "-l", "countries_110m", kCountries, dst}), dst);
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  CPLSetConfigOption("OGR_SQLITE_JOURNAL", "WAL");
  GDALDataset* holder = GDALDataset::Open(dst.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE);
  CPLSetConfigOption("OGR_SQLITE_JOURNAL", nullptr);
  ASSERT_TRUE(holder);
  holder->ExecuteSQL("UPDATE regions SET cells = cells + 1", nullptr, nullptr);  // pages in the -wal
  ASSERT_TRUE(fs::exists(dst + "-wal"));
  const Result r = run_small({"-q", "-overwrite", "-level", "5", "-layers", "regions", "-l", "countries_110m",
                              kCountries, dst});
  expect_success(r, dst);
  EXPECT_FALSE(fs::exists(dst + "-wal"));
  EXPECT_FALSE(fs::exists(dst + "-shm"));
  const auto check = [&] {
    const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
    ASSERT_TRUE(ds);
    OGRLayer* result = ds->ExecuteSQL("PRAGMA integrity_check", nullptr, nullptr);
    ASSERT_TRUE(result);
    const std::unique_ptr<OGRFeature> row(result->GetNextFeature());
    ASSERT_TRUE(row);
    EXPECT_STREQ(row->GetFieldAsString(0), "ok");
    ds->ReleaseResultSet(result);
    EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), 177);
  };
  check();
  GDALClose(holder);  // the other program closes its old file: the new one is untouched
  check();
}

TEST(CatalogueOutput, FifoAmongTheTileProductsIsRefusedInsteadOfBlocking) {
  const std::string dir = test_dir();
  const std::string tiles = dir + "/tiles";
  fs::create_directory(tiles);
  const Result tile = run(concat(concat({"-q", "-level", "5", "-device", "cpu", "-tile", "1/2"}, kCsvOptions),
                                 {kCentres, tiles + "/1.qtmt"}));
  ASSERT_EQ(tile.status, 0) << tile.err;
  ASSERT_EQ(mkfifo((tiles + "/2.qtmt").c_str(), 0600), 0);
  const std::string dst = dir + "/merged.gpkg";
  expect_failure(run(concat(concat({"-level", "5", "-merge", tiles}, kCsvOptions), {kCentres, dst}), {}, 20), 1,
                 {"-merge: '" + tiles + "/2.qtmt': not a regular file (a FIFO)"}, dst);
}

TEST(CatalogueOutput, TileJobUnderAnotherFormatsNameIsRefused) {
  // A tile product named part1.gpkg would look like a GeoPackage that GIS software cannot open.
  const std::string dir = test_dir();
  const std::string dst = dir + "/part1.gpkg";
  expect_failure(run(concat(concat({"-level", "5", "-device", "cpu", "-tile", "1/8"}, kCsvOptions), {kCentres, dst})),
                 1, {"-tile: '" + dst + "': a tile job writes a tile product, which only -merge reads: name it with .qtmt"},
                 dst);
}

TEST(CatalogueOutput, DatabaseDestinationsNotWrittenAllOrNothingAreRefusedBeforeAnyWork) {
  // A PostgreSQL destination is staged in a schema of its own (written for real on a throwaway
  // cluster: cli.PostgisDestinationIsWrittenAllOrNothing); what cannot be staged so is refused
  // before the source is read, and no staging directory is made for a connection string.
  const std::string dir = test_dir();
  const std::string pg = "PG:dbname=qtmv_nowhere host=" + dir + "/no_server";
  const auto refused = [&](const std::vector<std::string>& options, const std::string& dst, const std::string& message) {
    const Result r = run(concat(concat(concat({"-level", "5", "-device", "cpu"}, kCsvOptions), options), {kCentres, dst}));
    expect_failure(r, 1, {message}, dir + "/out.gpkg");
    EXPECT_FALSE(contains(r.err, "site(s) got no cell")) << "worked before refusing: " << r.err;
    EXPECT_TRUE(hidden_entries(fs::current_path().string()).empty());
  };
  refused({"-of", "MySQL"}, "MYSQL:qtmv,user=nobody",
          "-of MySQL: a database destination is written all or nothing only in PostgreSQL (PG:...)");
  refused({"-raster", "lonlat", "-ts", "20", "10"}, pg, "the PostgreSQL driver cannot write rasters");
  refused({"-of", "PostGISRaster"}, pg, "a PostgreSQL connection is written as vector output (PostgreSQL driver), not with PostGISRaster");
  refused({"-dsco", "A=B"}, pg, "-dsco: a PostgreSQL database has no dataset creation options");
  refused({"-of", "PostgreSQL"}, dir + "/out.gpkg", "a PostgreSQL destination is a connection string: PG:dbname=NAME");
  refused({}, "PG:postgresql://localhost/qtmv_nowhere", "a URI (PG:postgresql://...) cannot name the schema");
  refused({}, pg + " password=secret", "cannot write 'PG:dbname=qtmv_nowhere host=" + dir + "/no_server password=***': cannot connect to the database");
}

TEST(CatalogueOutput, PartsThatCannotBeCutOrIndexedAreRefused) {
  // A part holds what can be cut at a tile's edge, in a GeoPackage (or a band of a raster's rows);
  // an index needs every part, all of one kind.
  const std::string dir = test_dir();
  const auto tile = [&](const std::vector<std::string>& extra, const std::string& dst) {
    return run(concat(concat(concat({"-q", "-level", "5", "-device", "cpu", "-tile", "1/2", "-part"}, extra), kCsvOptions),
                      {kCentres, dst}));
  };
  expect_failure(tile({"-layers", "regions,voronoi_edges"}, dir + "/1.gpkg"), 1,
                 {"-part: a part holds no voronoi_edges layer"}, dir + "/1.gpkg");
  expect_failure(tile({}, dir + "/1.fgb"), 1, {"-part: a part is a GeoPackage", "not FlatGeobuf"}, dir + "/1.fgb");
  expect_failure(tile({"-bands", "fid"}, dir + "/1.gpkg"), 1, {"-bands is for raster output; GPKG output is vector"},
                 dir + "/1.gpkg");
  // A lon/lat raster part is a band of its rows: no more tiles than rows.
  expect_failure(run(concat(concat({"-q", "-level", "5", "-device", "cpu", "-tile", "1/40", "-part", "-ts", "64", "32"},
                                   kCsvOptions),
                            {kCentres, dir + "/1.tif"})),
                 1, {"-tile 1/40: the raster has 32 rows, fewer than the 40 tiles"}, dir + "/1.tif");
  const std::string parts = dir + "/parts";
  fs::create_directory(parts);
  ASSERT_EQ(tile({}, parts + "/1.gpkg").status, 0);
  const std::string index = dir + "/index.vrt";
  expect_failure(run({"-merge", parts, "-of", "VRT", index}), 1, {"-merge: 1 of the 2 parts missing (tile 2)"}, index);
  expect_failure(run({"-merge", parts, "-of", "VRT", kCentres, index}), 2, {"reads no source"}, index);
  // Raster parts: an incomplete set; a set with a vector part.
  const std::string rasters = dir + "/rasters";
  fs::create_directory(rasters);
  ASSERT_EQ(tile({"-raster", "lonlat"}, rasters + "/1.tif").status, 0);
  expect_failure(run({"-merge", rasters, "-of", "VRT", index}), 1, {"-merge: 1 of the 2 parts missing (tile 2)"},
                 index);
  expect_failure(run({"-merge", rasters + "/1.tif", "-merge", parts + "/1.gpkg", index}), 1,
                 {"a vector part, but '" + rasters + "/1.tif' is a raster part", "all raster or all vector"}, index);
}

TEST(CatalogueOptions, SitesSharingAFidAreRefusedForARaster) {
  // A -sql UNION of two layers gives sites FIDs 1, 2, 1, 2: the FID band could not tell them apart.
  const std::string dir = test_dir();
  const std::string src = make_dataset(dir + "/places.gpkg", "GPKG", "towns", "EPSG:4326",
                                       points({"POINT (10 10)", "POINT (20 20)"}));
  {
    const auto ds = qtmv::test::open_dataset(src, GDAL_OF_VECTOR | GDAL_OF_UPDATE);
    ASSERT_TRUE(ds);
    OGRLayer* villages = ds->CreateLayer("villages", ds->GetLayerByName("towns")->GetSpatialRef(), wkbPoint, nullptr);
    for (const double x : {-30.0, -40.0}) {
      OGRFeature feature(villages->GetLayerDefn());
      OGRPoint point(x, 5);
      feature.SetGeometry(&point);
      ASSERT_EQ(villages->CreateFeature(&feature), OGRERR_NONE);
    }
  }
  const std::string dst = dir + "/out.tif";
  expect_failure(run_small({"-sql", "SELECT fid, geom FROM towns UNION ALL SELECT fid, geom FROM villages", src, dst}),
                 1, {"several sites share FID 1, 2: a raster's FID band could not tell them apart"}, dst);
  // Vector output keeps all four.
  EXPECT_EQ(regions_of(src, dir + "/out.gpkg", {"-sql", "SELECT fid, geom FROM towns UNION ALL SELECT fid, geom FROM villages"}).size(), 4u);
}

TEST(CatalogueOptions, BruteForceForARasterIsRefusedNotIgnored) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.tif";
  expect_failure(run_small({"-algorithm", "brute", "-l", "countries_110m", kCountries, dst}), 1,
                 {"-algorithm brute is for vector output; GTiff output is a raster"}, dst);
  // Its vector output honours it: the same regions as the tree's.
  EXPECT_EQ(regions_of(kCountries, dir + "/brute.gpkg", {"-l", "countries_110m", "-algorithm", "brute"}).size(),
            regions_of(kCountries, dir + "/hier.gpkg", {"-l", "countries_110m", "-algorithm", "hier"}).size());
}

TEST(CatalogueOptions, BadBandsAreRefusedNamingTheArgument) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.tif";
  // The list: names from fid, boundary, distance, each once.
  for (const auto& [list, says] : std::vector<std::pair<std::string, std::string>>{
           {"fid,fid", "-bands: 'fid,fid': band 'fid' named twice"},
           {"fid,Boundary,FID", "-bands: 'fid,Boundary,FID': band 'fid' named twice"},
           {"fid,height", "-bands: 'fid,height': 'height' is not a band; name bands from fid, boundary, distance"},
           {"", "-bands: '': a band name is empty"},
           {"fid,,distance", "-bands: 'fid,,distance': a band name is empty"}}) {
    expect_failure(run(concat(concat({"-bands", list}, kCsvOptions), {kCentres, dst})), 2, {says}, dst);
  }
  expect_failure(run({"in.csv", dst, "-bands"}), 2, {"option '-bands' needs a value"}, dst);
  expect_failure(run({"-bands", "fid", "-bands", "boundary", "in.csv", dst}), 2, {"-bands: given twice"}, dst);
  // Vector output has layers, not bands: refused as -layers is with a raster.
  expect_failure(run({"-layers", "regions", "-bands", "fid", "in.csv", dst}), 2,
                 {"-bands is for raster output, -layers for vector output"}, dst);
  expect_failure(run({"-bands", "fid", "-layers", "regions", "in.csv", dst}), 2,
                 {"-bands is for raster output, -layers for vector output"}, dst);
  const std::string gpkg = dir + "/out.gpkg";
  expect_failure(run_small(concat(concat({"-bands", "fid"}, kCsvOptions), {kCentres, gpkg})), 1,
                 {"-bands is for raster output; GPKG output is vector"}, gpkg);
  // A tile job writes no raster, and -merge writes vector output.
  const std::string product = dir + "/t.qtmt";
  expect_failure(run(concat(concat({"-tile", "1/4", "-bands", "fid"}, kCsvOptions), {kCentres, product})), 2,
                 {"-bands is for a raster, which a whole run writes, or tile jobs in parts with -part (-merge "
                  "writes vector output)"},
                 product);
  expect_failure(run_small(concat(concat({"-merge", dir, "-bands", "fid"}, kCsvOptions), {kCentres, gpkg})), 1,
                 {"-bands is for raster output; GPKG output is vector"}, gpkg);
  expect_failure(run_small(concat(concat({"-merge", dir, "-bands", "fid"}, kCsvOptions), {kCentres, dst})), 1,
                 {"-merge joins tile products into vector output"}, dst);
  // The FID band alone (an allocation raster) keeps -ot's checks of the FIDs; the boundary band
  // alone writes no FID, so no FID is checked.
  const std::string src = write_text(dir + "/ids.geojson",
                                     "{\"type\":\"FeatureCollection\",\"features\":["
                                     "{\"type\":\"Feature\",\"id\":70000,\"properties\":{},"
                                     "\"geometry\":{\"type\":\"Point\",\"coordinates\":[10,10]}},"
                                     "{\"type\":\"Feature\",\"id\":3,\"properties\":{},"
                                     "\"geometry\":{\"type\":\"Point\",\"coordinates\":[-60,20]}}]}");
  expect_failure(run_small({"-bands", "fid", "-ot", "UInt16", src, dst}), 1,
                 {"band 1 (site_fid): site 0 has FID 70000, which UInt16 does not hold exactly", "choose a wider -ot"},
                 dst);
  expect_failure(run_small({"-bands", "distance,fid", "-ot", "UInt16", src, dst}), 1,
                 {"band 2 (site_fid): site 0 has FID 70000"}, dst);
  expect_success(run_small({"-q", "-bands", "boundary", "-ot", "Byte", src, dst}), dst);
}

TEST(CatalogueOutput, ZipBasedFormatsAreWritten) {
  // GDAL's /vsizip/ took the staging directory ".areas.xlsx.tmpXXXXXX" for the archive.
  const std::string dir = test_dir();
  const std::string xlsx = dir + "/areas.xlsx";
  expect_success(run_small({"-q", "-of", "XLSX", "-layers", "regions", "-l", "countries_110m", kCountries, xlsx}), xlsx);
  const auto ds = qtmv::test::open_dataset(xlsx, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), 177);
  const std::string kmz = dir + "/x.kmz";
  expect_success(run_small({"-q", "-of", "KMLSUPEROVERLAY", "-l", "countries_110m", kCountries, kmz}), kmz);
  EXPECT_TRUE(qtmv::test::open_dataset(kmz, GDAL_OF_RASTER));
}

TEST(CatalogueOutput, ShapefileTextIsUtf8) {
  // The driver's default, ISO-8859-1, mangled every name beyond Latin-1.
  const std::string dir = test_dir();
  const std::string src = write_text(dir + "/cities.geojson", R"({"type":"FeatureCollection","features":[
{"type":"Feature","properties":{"name":"東京"},"geometry":{"type":"Point","coordinates":[139.7,35.7]}},
{"type":"Feature","properties":{"name":"Москва"},"geometry":{"type":"Point","coordinates":[37.6,55.8]}},
{"type":"Feature","properties":{"name":"Zürich"},"geometry":{"type":"Point","coordinates":[8.5,47.4]}}]})");
  const std::string dst = dir + "/out.shp";
  expect_success(run_small({"-q", "-layers", "regions", src, dst}), dst);
  EXPECT_EQ(qtmv::test::read_file(dir + "/out.cpg"), "UTF-8");
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  std::set<std::string> names;
  for (auto& f : *ds->GetLayer(0)) names.insert(f->GetFieldAsString("name"));
  EXPECT_EQ(names, (std::set<std::string>{"東京", "Москва", "Zürich"}));
}

TEST(CatalogueOutput, NetCdfRasterKeepsItsQtmMetadata) {
  // netCDF refuses single metadata items: the run failed on QTM_LEVEL.
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  if (GDALGetDriverByName("netCDF") == nullptr) GTEST_SKIP() << "no netCDF driver";
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.nc";
  expect_success(run_small({"-q", "-of", "netCDF", "-raster", "lonlat", "-ts", "360", "180", "-l", "countries_110m",
                            kCountries, dst}), dst);
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_RASTER);
  ASSERT_TRUE(ds);
  EXPECT_STREQ(ds->GetMetadataItem("NC_GLOBAL#QTM_LEVEL"), "4");
  EXPECT_STREQ(ds->GetMetadataItem("NC_GLOBAL#QTM_LAYOUT"), "lonlat");
}

TEST(CatalogueOutput, AttributeTypeTheFormatCannotHoldBecomesText) {
  const std::string dir = test_dir();
  // List fields: GeoJSON has them, shapefiles do not. As ogr2ogr does, they are written as
  // String, with a warning naming the layer and the field, and nothing is lost.
  const std::string src = write_text(dir + "/lists.geojson", R"({"type":"FeatureCollection","features":[
{"type":"Feature","properties":{"tags":["a","b"],"ids":[7,8,9]},"geometry":{"type":"Point","coordinates":[3,4]}}]})");
  const std::string dst = dir + "/out.shp";
  const Result r = run_small({"-layers", "regions", src, dst});
  expect_success(r, dst);
  // The warning names the destination, not the temporary file the writer was writing.
  EXPECT_TRUE(contains(r.err, dst + ", layer regions: the ESRI Shapefile driver has no StringList fields: field "
                                    "tags written as String"))
      << r.err;
  EXPECT_FALSE(contains(r.err, ".tmp")) << r.err;
  EXPECT_TRUE(contains(r.err, "no IntegerList fields: field ids written as String")) << r.err;
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  OGRLayer* layer = ds->GetLayer(0);
  ASSERT_EQ(layer->GetFeatureCount(), 1);
  const auto f = std::unique_ptr<OGRFeature>(layer->GetNextFeature());
  EXPECT_EQ(f->GetFieldDefnRef(f->GetFieldIndex("tags"))->GetType(), OFTString);
  EXPECT_STREQ(f->GetFieldAsString("tags"), "(2:a,b)");
  EXPECT_STREQ(f->GetFieldAsString("ids"), "(3:7,8,9)");
}

TEST(CatalogueOutput, CompositeSitesWithOneFieldOfTwoTypesKeepEveryValue) {
  // "code" is Integer in towns, String in wells: the union was Integer (the first layer's type)
  // and "W-17", "N/A" became 0 with GDAL's warning naming no layer. Now String, with a warning;
  // Integer and Integer64 make Integer64, Integer and Real make Real (0.1 + 0.2 to the last bit).
  const std::string dir = test_dir();
  const std::string src = dir + "/places.gpkg";
  {
    GDALAllRegister();
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GPKG")->Create(src.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    ASSERT_TRUE(ds);
    OGRSpatialReference wgs84;
    wgs84.importFromEPSG(4326);
    struct Field {
      const char* name;
      OGRFieldType type;
    };
    const auto add_layer = [&](const char* name, const std::vector<Field>& fields,
                               const std::vector<std::pair<double, std::vector<std::string>>>& rows) {
      OGRLayer* layer = ds->CreateLayer(name, &wgs84, wkbPoint, nullptr);
      ASSERT_TRUE(layer);
      for (const Field& f : fields) {
        OGRFieldDefn defn(f.name, f.type);
        ASSERT_EQ(layer->CreateField(&defn), OGRERR_NONE);
      }
      for (const auto& [x, values] : rows) {
        OGRFeature feature(layer->GetLayerDefn());
        for (std::size_t k = 0; k < values.size(); ++k) feature.SetField(static_cast<int>(k), values[k].c_str());
        OGRPoint point(x, 10);
        feature.SetGeometry(&point);
        ASSERT_EQ(layer->CreateFeature(&feature), OGRERR_NONE);
      }
    };
    add_layer("towns", {{"code", OFTInteger}, {"pop", OFTInteger}, {"depth", OFTInteger}},
              {{10, {"17", "1200", "3"}}, {20, {"42", "800", "4"}}});
    add_layer("wells", {{"code", OFTString}, {"pop", OFTInteger64}, {"depth", OFTReal}},
              {{-30, {"W-17", "5000000000", "0.30000000000000004"}}, {-40, {"N/A", "7", "2.5"}}});
  }
  const std::string dst = dir + "/out.gpkg";
  const Result r = run_small({"-layers", "regions", "-l", "towns", "-l", "wells", src, dst});
  expect_success(r, dst);
  EXPECT_TRUE(contains(r.err, "warning: field 'code': Integer in layer 'towns', String in layer 'wells': written as String"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "field 'pop': Integer in layer 'towns', Integer64 in layer 'wells': written as Integer64"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "field 'depth': Integer in layer 'towns', Real in layer 'wells': written as Real")) << r.err;
  EXPECT_FALSE(contains(r.err, "Warning 1")) << r.err;  // GDAL's own, naming no layer
  const auto ds = qtmv::test::open_dataset(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds && ds->GetLayerByName("regions"));
  OGRLayer* regions = ds->GetLayerByName("regions");
  const OGRFeatureDefn* defn = regions->GetLayerDefn();
  EXPECT_EQ(defn->GetFieldDefn(defn->GetFieldIndex("code"))->GetType(), OFTString);
  EXPECT_EQ(defn->GetFieldDefn(defn->GetFieldIndex("pop"))->GetType(), OFTInteger64);
  EXPECT_EQ(defn->GetFieldDefn(defn->GetFieldIndex("depth"))->GetType(), OFTReal);
  std::vector<std::string> codes, layers;
  std::vector<GIntBig> pops;
  std::vector<double> depths;
  for (auto& f : *regions) {
    codes.push_back(f->GetFieldAsString("code"));
    layers.push_back(f->GetFieldAsString("site_layer"));
    pops.push_back(f->GetFieldAsInteger64("pop"));
    depths.push_back(f->GetFieldAsDouble("depth"));
  }
  EXPECT_EQ(codes, (std::vector<std::string>{"17", "42", "W-17", "N/A"}));
  EXPECT_EQ(layers, (std::vector<std::string>{"towns", "towns", "wells", "wells"}));
  EXPECT_EQ(pops, (std::vector<GIntBig>{1200, 800, 5000000000LL, 7}));
  EXPECT_EQ(depths, (std::vector<double>{3, 4, 0.1 + 0.2, 2.5}));

  // Real and String make String: the Real written to its last bit, not as OGR's 16 digits ("0.3").
  // A shapefile (the regions through OGR features) as well.
  const std::string shp = dir + "/mixed.shp";
  {
    const auto up = qtmv::test::open_dataset(src, GDAL_OF_VECTOR | GDAL_OF_UPDATE);
    ASSERT_TRUE(up);
    OGRLayer* depths_layer = up->CreateLayer("gauges", up->GetLayerByName("towns")->GetSpatialRef(), wkbPoint, nullptr);
    OGRFieldDefn code("code", OFTReal);
    ASSERT_EQ(depths_layer->CreateField(&code), OGRERR_NONE);
    OGRFeature feature(depths_layer->GetLayerDefn());
    feature.SetField(0, 0.1 + 0.2);
    OGRPoint point(100, -20);
    feature.SetGeometry(&point);
    ASSERT_EQ(depths_layer->CreateFeature(&feature), OGRERR_NONE);
  }
  const Result mixed = run_small({"-layers", "regions", "-l", "gauges", "-l", "wells", src, shp});
  expect_success(mixed, shp);
  EXPECT_TRUE(contains(mixed.err, "field 'code': Real in layer 'gauges', String in layer 'wells': written as String"))
      << mixed.err;
  const auto out = qtmv::test::open_dataset(shp, GDAL_OF_VECTOR);
  ASSERT_TRUE(out);
  codes.clear();
  for (auto& f : *out->GetLayer(0)) codes.push_back(f->GetFieldAsString("code"));
  EXPECT_EQ(codes, (std::vector<std::string>{"0.30000000000000004", "W-17", "N/A"}));
}

TEST(CatalogueOutput, FlatGeobufNamesTheRowsItCannotHoldAndEveryRowIsCounted) {
  // 10 of the 241 country centres get no cell at level 5: their regions are empty, which
  // FlatGeobuf (GDAL 3.6) drops, as it drops null geometries: 231 rows, exit 0, not a word.
  const std::string dir = test_dir();
  const std::string fgb = dir + "/x.fgb";
  const std::vector<std::string> args = concat({"-level", "5", "-device", "cpu", "-layers", "regions"}, kCsvOptions);
  const Result r = run(concat(args, {kCentres, fgb}));
  expect_success(r, fgb);
  EXPECT_TRUE(contains(r.err, "'" + fgb + "', layer regions: FlatGeobuf drops rows without a geometry: the 10 site(s) "
                              "without a cell (FIDs 28, 73, 119, 131, 164, 165, 186, 189, 213, 241) are not in it"))
      << r.err;
  const auto read_fids = [](const std::string& path) {
    std::set<GIntBig> fids;
    const auto ds = qtmv::test::open_dataset(path, GDAL_OF_VECTOR);
    if (!ds) return fids;
    for (auto& f : *ds->GetLayer(0)) {
      EXPECT_TRUE(f->GetGeometryRef() == nullptr || !f->GetGeometryRef()->IsEmpty() ||
                  f->GetFieldAsInteger64("cells") == 0);
      fids.insert(f->GetFieldAsInteger64("site_fid"));
    }
    return fids;
  };
  const std::set<GIntBig> in_fgb = read_fids(fgb);
  EXPECT_EQ(in_fgb.size(), 231u);
  for (const GIntBig fid : {28, 73, 119, 131, 164, 165, 186, 189, 213, 241}) EXPECT_EQ(in_fgb.count(fid), 0u) << fid;

  // MapInfo refuses an empty geometry and keeps a null one: every row, those 10 without geometry.
  const std::string tab = dir + "/x.tab";
  const Result mapinfo = run(concat(concat(args, {"-of", "MapInfo File"}), {kCentres, tab}));
  expect_success(mapinfo, tab);
  {
    const auto ds = qtmv::test::open_dataset(tab, GDAL_OF_VECTOR);
    ASSERT_TRUE(ds);
    std::set<GIntBig> without;
    GIntBig rows = 0;
    for (auto& f : *ds->GetLayer(0)) {
      ++rows;
      if (f->GetGeometryRef() == nullptr) without.insert(f->GetFieldAsInteger64("site_fid"));
    }
    EXPECT_EQ(rows, 241);
    EXPECT_EQ(without, (std::set<GIntBig>{28, 73, 119, 131, 164, 165, 186, 189, 213, 241}));
  }

  // GeoPackage and Shapefile keep them (empty, or null in a shapefile): 241 rows.
  for (const std::string name : {"x.gpkg", "kept.shp"}) {
    const std::string dst = dir + "/" + name;
    const Result kept = run(concat(args, {kCentres, dst}));
    expect_success(kept, dst);
    EXPECT_FALSE(contains(kept.err, "drops rows")) << kept.err;
    EXPECT_EQ(read_fids(dst).size(), 241u) << name;
  }

  // The count check after writing: should the driver lose rows it was given (here the empties
  // written anyway, by fault injection), the run fails naming the count, and nothing is left.
  const std::string lost = dir + "/lost.fgb";
  expect_failure(run(concat(concat(args, {"--config", "QTMV_FAULT_EMPTY_ROWS", "EMPTY"}), {kCentres, lost})), 1,
                 {lost + ", layer regions: 241 rows written, but the FlatGeobuf file holds 231 of them"}, lost);
}

// A file system that fills up: the run's file size limit (ulimit -f). The write fails, the run
// says where, and nothing is left: neither the destination nor the temporary directory.
void expect_disk_full(const std::vector<std::string>& args, const std::string& dst, long bytes,
                      const std::vector<std::string>& names) {
  const Result r = run_small(concat(args, {"-l", "countries_110m", kCountries, dst}), ChildSetup{bytes, false});
  expect_failure(r, 1, names, dst);
}

TEST(CatalogueOutput, DiskFullWritingGeoPackage) {
  const std::string dir = test_dir();
  expect_disk_full({"-layers", "cells"}, dir + "/out.gpkg", 64 << 10, {dir + "/out.gpkg, layer cells", "I/O error"});
}

TEST(CatalogueOutput, DiskFullWritingGeoTiff) {
  const std::string dir = test_dir();
  expect_disk_full({"-level", "7"}, dir + "/out.tif", 16 << 10, {dir + "/out.tif", "File too large"});
}

TEST(CatalogueOutput, DiskFullWritingShapefile) {
  const std::string dir = test_dir();
  expect_disk_full({"-layers", "boundary_cells"}, dir + "/out.shp", 8 << 10, {dir + "/out.shp", "File too large"});
}

TEST(CatalogueOutput, SigintWhileWritingLeavesNothing) {
  qtmv::test::expect_clean_stop_while_writing(concat({kCentres}, kCsvOptions), SIGINT, "SIGINT", 1.5);
}

TEST(CatalogueOutput, SigintWhileStreamingARasterLeavesNothing) {
  // Level 11 centres as a QTM-coded raster: seconds of strips; SIGINT once the writer has begun.
  const std::string dir = test_dir();
  const std::string dst = dir + "/centres.tif";
  double seconds = 0;
  const Result r = qtmv::test::interrupt_when(
      concat({"-level", "11", "-device", "cpu", kCentres, dst}, kCsvOptions),
      [&](const std::string&) { return qtmv::test::writing(dir, "centres.tif"); }, SIGINT, seconds);
  qtmv::test::expect_interrupted(r, "SIGINT", dst, seconds, 3.0);
}

// ---------------------------------------------------------------------------------------------
// Limits announced before the work

TEST(CatalogueLimits, LevelTooLargeForMemoryFailsBeforeReading) {
  const std::string dir = test_dir();
  const auto start = std::chrono::steady_clock::now();
  // The source does not exist: the estimate comes first.
  const Result r = run({"-level", "24", "-device", "cpu", dir + "/missing.gpkg", dir + "/out.gpkg"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  expect_failure(r, 1, {"level 24 needs about ", " GiB for its outline cells", "choose a lower -level"},
                 dir + "/out.gpkg");
  EXPECT_FALSE(contains(r.err, "missing.gpkg")) << r.err;
  // A raster is written strip by strip: its memory follows the strip, not the level's 8.8
  // trillion cells, and what stops level 20 is the disk (2 million x 8 million pixels).
  const Result raster = run({"-level", "20", "-device", "cpu", dir + "/missing.gpkg", dir + "/out.tif"});
  expect_failure(raster, 1, {"the raster takes about ", " TB uncompressed", "choose a lower -level"}, dir + "/out.tif");
  EXPECT_FALSE(contains(raster.err, "needs about")) << raster.err;
  EXPECT_FALSE(contains(raster.err, "missing.gpkg")) << raster.err;
}

TEST(CatalogueLimits, RasterLargerThanTheFreeDiskSpaceFailsBeforeReading) {
  const std::string dir = test_dir();
  const auto start = std::chrono::steady_clock::now();
  // The issue's 10^12-pixel raster: 24 TB uncompressed. The source does not exist: the
  // estimate comes first, before any work.
  const Result r = run_small({"-ts", "1000000", "1000000", dir + "/missing.gpkg", dir + "/out.tif"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  expect_failure(r, 1,
                 {"'" + dir + "/out.tif': the raster takes about 12.0 TB uncompressed (1000000 x 1000000 pixels, 3 "
                  "bands of Float32) and '" + dir + "' has ",
                  " free: choose fewer pixels (-tr, -ts); for an output that compresses well or is sparse, add "
                  "--config CHECK_DISK_FREE_SPACE NO"},
                 dir + "/out.tif");
  EXPECT_FALSE(contains(r.err, "missing.gpkg")) << r.err;
}

TEST(CatalogueLimits, CellsLayerLargerThanTheFreeDiskSpaceNeedsTheConfigOption) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/pts.csv", {"POINT (10 10)", "POINT (-100 40)"});
  // A file system with 100 kB free (fault injection) and 2048 cells of about 150 bytes.
  const std::vector<std::string> small_disk{"--config", "QTMV_FAULT_DISK_FREE_BYTES", "100000", "-layers", "cells"};
  expect_failure(run_small(concat(small_disk, {src, dir + "/out.gpkg"})), 1,
                 {"'" + dir + "/out.gpkg': the cells layer takes about 307.2 kB (2048 rows of about 150 bytes) and '" +
                      dir + "' has 100.0 kB free: choose a lower -level, or -layers without cells",
                  "CHECK_DISK_FREE_SPACE NO"},
                 dir + "/out.gpkg");
  // GDAL's own switch lets it through; 2048 rows written.
  const Result r = run_small(concat(concat(small_disk, {"--config", "CHECK_DISK_FREE_SPACE", "NO"}), {src, dir + "/out.gpkg"}));
  expect_success(r, dir + "/out.gpkg");
  const auto ds = qtmv::test::open_dataset(dir + "/out.gpkg", GDAL_OF_VECTOR);
  ASSERT_TRUE(ds && ds->GetLayerByName("cells"));
  EXPECT_EQ(ds->GetLayerByName("cells")->GetFeatureCount(), 2048);
  // Without the cells layer the output is small: no refusal.
  expect_success(run_small({"--config", "QTMV_FAULT_DISK_FREE_BYTES", "100000", "-layers", "regions", src,
                            dir + "/regions.gpkg"}),
                 dir + "/regions.gpkg");
}

TEST(CatalogueLimits, ADiskThatFillsWhileTheFileIsWrittenBehindLosesNothing) {
  const std::string dir = test_dir();
  const std::string src = wkt_csv(dir + "/pts.csv", {"POINT (10 10)", "POINT (-100 40)", "POINT (50 -30)"});
  // The GeoPackage's writes fail as on a full disk once 200 kB are written (fault injection), on
  // the file's own thread (write/sqlite_write_behind.hpp): the run fails at the commit that waits
  // for them, names the destination, and leaves neither a file nor a temporary one.
  const std::vector<std::string> args{"--config", "QTMV_FAULT_WRITE_BEHIND_BYTES", "200000", "-level", "12",
                                      "-layers", "regions,boundary_cells"};
  // Two threads, so that the file has its own on a host of one core too.
  expect_failure(run(concat(args, {"-device", "cpu", "-threads", "2", src, dir + "/out.gpkg"})), 1,
                 {dir + "/out.gpkg, layer ", "database or disk is full"}, dir + "/out.gpkg");
  // With -overwrite, the old file is kept as it was.
  write_text(dir + "/old.gpkg", "the user's file");
  expect_failure(run(concat(args, {"-device", "cpu", "-threads", "2", "-overwrite", src, dir + "/old.gpkg"})), 1,
                 {dir + "/old.gpkg, layer ", "database or disk is full"}, dir + "/none.gpkg");
  std::ifstream old(dir + "/old.gpkg");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(old), std::istreambuf_iterator<char>()), "the user's file");
  // Written from SQLite's thread (QTMV_WRITE_BEHIND NO, or a run of one thread), no write is
  // behind to fail: every row.
  expect_success(run(concat(args, {"-device", "cpu", "-threads", "1", src, dir + "/one.gpkg"})), dir + "/one.gpkg");
  expect_success(run(concat(args, {"--config", "QTMV_WRITE_BEHIND", "NO", "-device", "cpu", src, dir + "/ok.gpkg"})),
                 dir + "/ok.gpkg");
  const auto ds = qtmv::test::open_dataset(dir + "/ok.gpkg", GDAL_OF_VECTOR);
  ASSERT_TRUE(ds && ds->GetLayerByName("regions") && ds->GetLayerByName("boundary_cells"));
  EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), 3);
  EXPECT_GT(ds->GetLayerByName("boundary_cells")->GetFeatureCount(), 1000);
}

TEST(CatalogueLimits, ClusteredLinesWhoseTreeCannotFitAreRefused) {
  const std::string dir = test_dir();
  // 300 lines of about 50 m in a box of 0.02 degrees, and 3 points far away: every node far from
  // the box keeps the lines, four times the entries a level. On a host with 50 MB to give (fault
  // injection) the tree stops before a level it could not hold, and says why.
  std::vector<std::string> wkts;
  for (int k = 0; k < 300; ++k) {
    const double x = 10.0 + 0.02 * ((k * 37) % 300) / 300.0, y = 45.0 + 0.02 * ((k * 91) % 300) / 300.0;
    wkts.push_back("LINESTRING (" + std::to_string(x) + " " + std::to_string(y) + ", " + std::to_string(x + 0.0005) +
                   " " + std::to_string(y + 0.0003) + ")");
  }
  for (const char* far : {"POINT (-120 30)", "POINT (100 -40)", "POINT (0 -80)"}) wkts.emplace_back(far);
  const std::string src = wkt_csv(dir + "/cluster.csv", wkts);
  const std::vector<std::string> args{"-level", "8", "-device", "cpu", "-layers", "regions", src, dir + "/out.gpkg"};
  expect_failure(run(concat({"--config", "QTMV_FAULT_AVAILABLE_MEMORY", "50000000"}, args)), 1,
                 {"labelling failed: the labeller's tree would need up to", " at level 7 of 8 (",
                  "this host has free: sites in tight clusters far from most cells", "choose a lower -level"},
                 dir + "/out.gpkg");
  // On this host the same run fits.
  expect_success(run(args), dir + "/out.gpkg");
}

TEST(CatalogueLimits, SigintWhileLabellingStopsWithinASecond) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.gpkg";
  // Level 12 on the CPU: 134 million cells, seconds of labelling in tiles of 64 MiB. The
  // labeller says where it runs once the read is done and the labels are allocated.
  double seconds = 0;
  const Result r = qtmv::test::interrupt_when(
      concat({"-level", "12", "-device", "cpu", "-layers", "regions", kCentres, dst}, kCsvOptions),
      [](const std::string& err) { return contains(qtmv::test::read_file(err), "labelling on cpu"); }, SIGINT,
      seconds);
  qtmv::test::expect_interrupted(r, "SIGINT", dst, seconds, 3.0);
  EXPECT_FALSE(contains(r.err, "sites read,")) << "the run finished before the signal: " << r.err;
}

}  // namespace
