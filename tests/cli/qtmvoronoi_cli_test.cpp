// qtmvoronoi end to end: the built binary run as a user runs it, its outputs read back with GDAL
// and checked against the labeller; and the library entry point and the parser called directly.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <gtest/gtest.h>

#include "../test_temp_dir.hpp"
#include "qtmvoronoi_test_support.hpp"
#include "grid/qtm.hpp"
#include "label/labeller.hpp"
#include "pipeline/output_format.hpp"
#include "qtmv_version.hpp"
#include "qtmvoronoi_core.hpp"
#include "sites/ogr_site_reader.hpp"
#include "voronoi.hpp"

namespace {

namespace fs = std::filesystem;
namespace grid = qtmv::grid;
using qtmv::qtmvoronoi::parse_command_line;
using qtmv::qtmvoronoi::UsageError;

const std::string kTestdata = QTMV_TESTDATA_DIR;
const std::string kCentres = kTestdata + "/country_centres.csv";
const std::string kCountries = kTestdata + "/world_atlas_countries_110m.gpkg";
const std::vector<std::string> kCsvOptions{"-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat"};
constexpr double kEllipsoidArea = 5.10065621724088e14;  // WGS84, m^2 (GeographicLib's EllipsoidArea)

using Result = qtmv::test::ProcessResult;

std::string read_all(const std::string& path) { return qtmv::test::read_file(path); }

using qtmv::test::concat;
using qtmv::test::hidden_entries;
using qtmv::test::test_dir;

Result run(const std::vector<std::string>& args) { return qtmv::test::run_qtmvoronoi(args); }

GDALDatasetUniquePtr open(const std::string& path, unsigned flags) { return qtmv::test::open_dataset(path, flags); }

// The sites and labels the tool should have computed, from the library parts directly.
struct Reference {
  qtmv::sites::SiteSet sites;
  qtmv::label::LabelResult labels;
};
Reference reference(const std::string& source, int level, const std::vector<std::string>& open_options,
                    const std::string& layer = "") {
  qtmv::sites::ReadOptions ro;
  ro.level = level;
  if (!layer.empty()) ro.layers = {layer};
  ro.open_options = open_options;
  Reference r;
  r.sites = qtmv::sites::read_sites(source, ro);
  qtmv::label::LabelOptions lo;
  lo.device = "cpu";
  r.labels = qtmv::label::label_all(r.sites.geometry.input(), lo);
  return r;
}

// ---------------------------------------------------------------------------------------------
// The command line

TEST(QtmvoronoiCli, HelpAndVersion) {
  for (const char* option : {"--help", "-h", "-help"}) {
    const Result r = run({option});
    EXPECT_EQ(r.status, 0) << option;
    EXPECT_NE(r.out.find("SYNOPSIS"), std::string::npos) << option;
    EXPECT_NE(r.out.find("EXIT STATUS"), std::string::npos) << option;
  }
  const Result v = run({"--version"});
  EXPECT_EQ(v.status, 0);
  EXPECT_EQ(v.out.rfind(std::string("qtmvoronoi ") + QTMV_VERSION_STRING, 0), 0u) << v.out;
  EXPECT_NE(v.out.find("GDAL"), std::string::npos) << v.out;
}

TEST(QtmvoronoiCli, UsageErrorsExit2WithTheUsage) {
  const std::vector<std::vector<std::string>> cases{
      {},
      {"a.csv"},
      {"a.csv", "b.gpkg", "c.gpkg"},
      {"-bogus", "a.csv", "b.gpkg"},
      {"a.csv", "b.gpkg", "-level"},
      {"-level", "25", "a.csv", "b.gpkg"},
      {"-level", "x", "a.csv", "b.gpkg"},
      {"-tr", "1", "1", "-ts", "10", "10", "a.csv", "b.tif"},
      {"-raster", "qtm", "-tr", "1", "1", "a.csv", "b.tif"},
      {"-raster", "hex", "a.csv", "b.tif"},
      {"-ot", "Int8", "a.csv", "b.tif"},
      {"-ot", "CFloat32", "a.csv", "b.tif"},
      {"-layers", "regions,nope", "a.csv", "b.gpkg"},
      {"-vertices", "some", "a.csv", "b.gpkg"},
      {"-tile", "1/2", "-vertices", "all", "a.csv", "b.qtmt"},
      {"-device", "gpu", "a.csv", "b.gpkg"},
      {"-oo", "novalue", "a.csv", "b.gpkg"},
      {"--config", "ONLY_KEY"},
  };
  for (const auto& args : cases) {
    const Result r = run(args);
    std::string line;
    for (const auto& a : args) line += a + ' ';
    EXPECT_EQ(r.status, 2) << line << "\n" << r.err;
    EXPECT_NE(r.err.find("Usage:"), std::string::npos) << line << "\n" << r.err;
  }
}

TEST(QtmvoronoiCore, ParsesOptions) {
  const auto o = parse_command_line({"--level", "7", "-L", "layer", "-where", "a > 1", "-s_srs", "EPSG:3857",
                                     "-oo", "A=1", "-oo", "B=2", "-edges", "geodesic", "-wrap", "none", "-strict",
                                     "-distance", "cell", "-device", "CPU", "-algorithm", "brute", "-f", "GPKG",
                                     "-lco", "X=1", "-dsco", "Y=2", "-layers", "regions, cells", "-overwrite", "-q",
                                     "src.shp", "dst.gpkg"});
  EXPECT_EQ(o.run.level, 7);
  EXPECT_EQ(o.run.read.layers, (std::vector<std::string>{"layer"}));
  EXPECT_EQ(o.run.read.where, "a > 1");
  EXPECT_EQ(o.run.read.source_srs, "EPSG:3857");
  EXPECT_EQ(o.run.read.open_options, (std::vector<std::string>{"A=1", "B=2"}));
  EXPECT_EQ(o.run.read.edges, qtmv::sites::EdgeShape::geodesic);
  EXPECT_EQ(o.run.read.wrap, qtmv::sites::WrapMode::none);
  EXPECT_TRUE(o.run.read.strict);
  EXPECT_FALSE(o.run.read.make_valid);
  EXPECT_TRUE(parse_command_line({"-makevalid", "src.shp", "dst.gpkg"}).run.read.make_valid);
  EXPECT_TRUE(parse_command_line({"--MakeValid", "src.shp", "dst.gpkg"}).run.read.make_valid);
  EXPECT_EQ(o.run.rule, qtmv::label::Rule::cell);
  EXPECT_EQ(o.run.device, "cpu");
  EXPECT_EQ(o.run.algorithm, qtmv::label::Algorithm::brute);
  EXPECT_EQ(o.run.format, "GPKG");
  // The tool's default, as the library's options struct has it; and -algorithm auto.
  EXPECT_EQ(parse_command_line({"src.shp", "dst.gpkg"}).run.algorithm, qtmv::label::Algorithm::automatic);
  EXPECT_EQ(parse_command_line({"-algorithm", "AUTO", "src.shp", "dst.gpkg"}).run.algorithm,
            qtmv::label::Algorithm::automatic);
  EXPECT_EQ(qtmv::VoronoiOptions().algorithm, qtmv::label::Algorithm::automatic);
  EXPECT_EQ(o.run.vector.layers, (std::vector<std::string>{"regions", "cells"}));
  EXPECT_EQ(o.run.kind, qtmv::OutputKind::vector);
  EXPECT_TRUE(o.run.overwrite);
  EXPECT_TRUE(o.quiet);
  EXPECT_EQ(o.source, "src.shp");
  EXPECT_EQ(o.destination, "dst.gpkg");

  const auto d = parse_command_line({"in.csv", "out.tif"});
  EXPECT_EQ(d.run.level, qtmv::VoronoiOptions::kLevelFromOutput);  // the default: 9, or from a lon/lat raster's pixels
  EXPECT_EQ(d.run.kind, qtmv::OutputKind::automatic);
  EXPECT_FALSE(d.run.overwrite);

  const auto t = parse_command_line({"-tr", "0.5", "0.25", "in.csv", "out.tif"});  // -tr implies lonlat
  EXPECT_EQ(t.run.kind, qtmv::OutputKind::raster);
  EXPECT_EQ(t.run.raster.layout, qtmv::write::RasterOptions::Layout::lonlat);
  EXPECT_EQ(t.run.raster.x_resolution, 0.5);
  EXPECT_EQ(t.run.raster.y_resolution, 0.25);

  const auto ot = parse_command_line({"-ot", "uint16", "in.csv", "out.tif"});
  EXPECT_EQ(ot.run.raster.data_type, "uint16");
  EXPECT_TRUE(parse_command_line({"in.csv", "out.tif"}).run.raster.data_type.empty());
  EXPECT_THROW(parse_command_line({"-ot", "Int64", "a", "b"}), UsageError);
  using qtmv::write::RasterBand;
  EXPECT_EQ(parse_command_line({"-bands", "distance,fid", "in.csv", "out.tif"}).run.raster.bands,
            (std::vector<RasterBand>{RasterBand::distance, RasterBand::fid}));
  EXPECT_TRUE(parse_command_line({"in.csv", "out.tif"}).run.raster.bands.empty());  // all three
  EXPECT_THROW(parse_command_line({"-bands", "fid,fid", "a", "b"}), UsageError);

  EXPECT_THROW(parse_command_line({"-layers", "regions", "-raster", "qtm", "a", "b"}), UsageError);
  EXPECT_THROW(parse_command_line({"-tr", "0", "1", "a", "b"}), UsageError);
  EXPECT_THROW(parse_command_line({"-ts", "10", "a", "b"}), UsageError);
  EXPECT_THROW(parse_command_line({"-layers", "regions,regions", "a", "b"}), UsageError);
  EXPECT_TRUE(parse_command_line({"a", "--help"}).help);
  // Without -vertices, every vertex (the reading geodesic consumers need); the choice is recorded.
  EXPECT_EQ(o.run.vector.ring_vertices, qtmv::write::VectorLayers::Vertices::automatic);
  EXPECT_TRUE(o.run.vector.all_ring_vertices());
  EXPECT_EQ(parse_command_line({"-vertices", "ALL", "a", "b"}).run.vector.ring_vertices,
            qtmv::write::VectorLayers::Vertices::all);
  EXPECT_FALSE(parse_command_line({"-vertices", "corners", "a", "b"}).run.vector.all_ring_vertices());
}

TEST(QtmvoronoiCore, GuessesTheFormatFromGdalsDriverMetadata) {
  using qtmv::OutputKind;
  auto guess = [](const std::string& name, OutputKind kind = OutputKind::automatic) {
    return qtmv::choose_output_format(name, "", kind);
  };
  EXPECT_EQ(guess("x/out.gpkg").driver, "GPKG");
  EXPECT_FALSE(guess("out.gpkg").raster);
  EXPECT_TRUE(guess("out.gpkg", OutputKind::raster).raster);
  EXPECT_EQ(guess("out.shp").driver, "ESRI Shapefile");
  EXPECT_EQ(guess("out.GeoJSON").driver, "GeoJSON");
  EXPECT_EQ(guess("out.fgb").driver, "FlatGeobuf");
  EXPECT_EQ(guess("out.csv").driver, "CSV");
  EXPECT_EQ(guess("out.tif").driver, "GTiff");
  EXPECT_TRUE(guess("out.tiff").raster);
  EXPECT_EQ(guess("out.png").driver, "PNG");
  EXPECT_THROW(guess("out.nosuchextension"), qtmv::VoronoiError);
  EXPECT_THROW(guess("out"), qtmv::VoronoiError);
  EXPECT_THROW(guess("out.tif", OutputKind::vector), qtmv::VoronoiError);
  EXPECT_EQ(qtmv::choose_output_format("out.dat", "gtiff", OutputKind::automatic).driver, "GTiff");
  EXPECT_THROW(qtmv::choose_output_format("out.gpkg", "NoSuchDriver", OutputKind::automatic), qtmv::VoronoiError);
}

// ---------------------------------------------------------------------------------------------
// Outputs

TEST(QtmvoronoiCli, RegionsTileTheEllipsoid) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/centres.gpkg";
  const int level = 7;
  const Result r = run(concat({"-level", std::to_string(level), "-device", "cpu", kCentres, dst}, kCsvOptions));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("sites read"), std::string::npos) << r.err;  // the summary line
  EXPECT_TRUE(hidden_entries(dir).empty());

  const Reference ref = reference(kCentres, level, {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"});
  const auto ds = open(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  for (const char* name : {"regions", "boundary_cells", "voronoi_edges"}) EXPECT_TRUE(ds->GetLayerByName(name)) << name;
  OGRLayer* regions = ds->GetLayerByName("regions");
  ASSERT_TRUE(regions);
  EXPECT_EQ(regions->GetFeatureCount(), static_cast<GIntBig>(ref.sites.table.sites.size()));
  const OGRFeatureDefn* defn = regions->GetLayerDefn();
  for (const char* field : {"name", "site_fid", "cells", "area_m2"}) EXPECT_GE(defn->GetFieldIndex(field), 0) << field;

  std::vector<std::unique_ptr<OGRGeometry>> shapes;
  double area = 0;
  std::uint64_t cells = 0;
  std::size_t k = 0;
  for (auto& feature : *regions) {
    const OGRGeometry* g = feature->GetGeometryRef();
    ASSERT_TRUE(g);
    EXPECT_TRUE(g->IsValid()) << "site " << k;
    EXPECT_EQ(feature->GetFieldAsInteger64("site_fid"), ref.sites.table.sites[k].fid);
    area += feature->GetFieldAsDouble("area_m2");
    cells += static_cast<std::uint64_t>(feature->GetFieldAsInteger64("cells"));
    shapes.emplace_back(g->clone());
    ++k;
  }
  EXPECT_EQ(cells, grid::cell_count(level));
  EXPECT_NEAR(area / kEllipsoidArea, 1.0, 1e-4);
  // No two overlap (GEOS, a sample of pairs: neighbours in file order and random pairs).
  if (OGRGeometryFactory::haveGEOS()) {
    std::mt19937 random(5);
    for (int t = 0; t < 150; ++t) {
      const std::size_t a = t < 50 ? t : random() % shapes.size(), b = t < 50 ? t + 1 : random() % shapes.size();
      if (a == b || b >= shapes.size()) continue;
      std::unique_ptr<OGRGeometry> common(shapes[a]->Intersection(shapes[b].get()));
      const double overlap = common && common->getDimension() == 2 ? OGR_G_Area(OGRGeometry::ToHandle(common.get())) : 0;
      EXPECT_LT(overlap, 1e-9) << "sites " << a << " and " << b;
    }
  }
}

TEST(QtmvoronoiCli, RegionsOfPolygonSitesAreValid) {
  // Countries: enclaves and coasts make regions that meet themselves at single vertices.
  const std::string dir = test_dir();
  const std::string dst = dir + "/countries.gpkg";
  const int level = 7;
  const Result r = run({"-q", "-level", std::to_string(level), "-layers", "regions", "-l", "countries_110m", kCountries, dst});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto ds = open(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  OGRLayer* regions = ds->GetLayerByName("regions");
  ASSERT_TRUE(regions);
  EXPECT_EQ(regions->GetFeatureCount(), 177);
  double area = 0;
  std::uint64_t cells = 0;
  int invalid = 0;
  for (auto& feature : *regions) {
    const OGRGeometry* g = feature->GetGeometryRef();
    if (g && !g->IsEmpty() && !g->IsValid()) ++invalid;
    area += feature->GetFieldAsDouble("area_m2");
    cells += static_cast<std::uint64_t>(feature->GetFieldAsInteger64("cells"));
  }
  EXPECT_EQ(invalid, 0);
  EXPECT_EQ(cells, grid::cell_count(level));
  EXPECT_NEAR(area / kEllipsoidArea, 1.0, 1e-4);
}

TEST(QtmvoronoiCli, QtmRasterEqualsTheLabeller) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/countries_qtm.tif";
  const int level = 7;
  const Result r = run({"-q", "-level", std::to_string(level), "-l", "countries_110m", kCountries, dst});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find("sites read"), std::string::npos) << "-q prints no summary: " << r.err;

  const Reference ref = reference(kCountries, level, {}, "countries_110m");
  const auto ds = open(dst, GDAL_OF_RASTER);
  ASSERT_TRUE(ds);
  const int n = 1 << level;
  ASSERT_EQ(ds->GetRasterXSize(), 2 * n - 1);
  ASSERT_EQ(ds->GetRasterYSize(), 8 * n);
  ASSERT_EQ(ds->GetRasterCount(), 3);
  EXPECT_STREQ(ds->GetMetadataItem("QTM_LAYOUT"), "octant_row_col");
  EXPECT_EQ(std::string(ds->GetMetadataItem("QTM_LEVEL")), std::to_string(level));
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  std::vector<double> fid(std::size_t(w) * h), boundary(fid.size()), metres(fid.size());
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, fid.data(), w, h, GDT_Float64, 0, 0), CE_None);
  ASSERT_EQ(ds->GetRasterBand(2)->RasterIO(GF_Read, 0, 0, w, h, boundary.data(), w, h, GDT_Float64, 0, 0), CE_None);
  ASSERT_EQ(ds->GetRasterBand(3)->RasterIO(GF_Read, 0, 0, w, h, metres.data(), w, h, GDT_Float64, 0, 0), CE_None);
  std::uint64_t mismatches = 0, nodata_bad = 0;
  for (int o = 0; o < 8; ++o) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < w; ++j) {
        const std::size_t p = std::size_t(o * n + i) * w + j;
        if (j > 2 * i) {
          nodata_bad += fid[p] != -1;
          continue;
        }
        const grid::Code code = grid::Code(o) * n * n + grid::Code(i) * i + j;
        const auto s = static_cast<std::size_t>(ref.labels.site[code]);
        mismatches += fid[p] != double(ref.sites.table.sites[s].fid) || boundary[p] != ref.labels.boundary[code] ||
                      metres[p] != double(ref.labels.distance_m[code]);
      }
    }
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(nodata_bad, 0u);
}

TEST(QtmvoronoiCli, LonLatRasterWithoutALevelTakesCellsFourTimesFinerThanAPixel) {
  const std::string dir = test_dir();
  struct Case {
    std::vector<std::string> size;
    int level;  // the smallest L with 90 / 2^L <= pixel / 4 (degrees)
  };
  for (const Case& c : {Case{{"-tr", "0.5", "0.5"}, 10}, Case{{"-ts", "360", "180"}, 9}, Case{{"-tr", "2", "1"}, 9}}) {
    const std::string dst = dir + "/auto_" + std::to_string(c.level) + "_" + c.size[1] + ".tif";
    const Result r = run(concat(concat(c.size, {"-device", "cpu", kCentres, dst}), kCsvOptions));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("level " + std::to_string(c.level) + " chosen for pixels of"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("; level " + std::to_string(c.level) + ", "), std::string::npos) << r.err;  // the summary
    const auto ds = open(dst, GDAL_OF_RASTER);
    ASSERT_TRUE(ds);
    EXPECT_STREQ(ds->GetMetadataItem("QTM_LEVEL"), std::to_string(c.level).c_str());
  }
  // -level still decides; a QTM-coded raster keeps the default.
  const Result given = run(concat({"-level", "6", "-tr", "0.5", "0.5", "-device", "cpu", kCentres, dir + "/given.tif"}, kCsvOptions));
  ASSERT_EQ(given.status, 0) << given.err;
  EXPECT_EQ(given.err.find("chosen for pixels"), std::string::npos) << given.err;
  EXPECT_STREQ(open(dir + "/given.tif", GDAL_OF_RASTER)->GetMetadataItem("QTM_LEVEL"), "6");
}

TEST(QtmvoronoiCli, LonLatRasterAgreesWithPointLocation) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/centres_lonlat.tif";
  const int level = 6;
  const Result r =
      run(concat({"-level", std::to_string(level), "-ts", "720", "360", kCentres, dst, "-device", "cpu"}, kCsvOptions));
  ASSERT_EQ(r.status, 0) << r.err;
  const Reference ref = reference(kCentres, level, {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"});
  const auto ds = open(dst, GDAL_OF_RASTER);
  ASSERT_TRUE(ds);
  ASSERT_EQ(ds->GetRasterXSize(), 720);
  ASSERT_EQ(ds->GetRasterYSize(), 360);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  const int w = 720, h = 360;
  std::vector<double> fid(std::size_t(w) * h);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, fid.data(), w, h, GDT_Float64, 0, 0), CE_None);
  std::mt19937 random(9);
  int mismatches = 0;
  for (int t = 0; t < 20000; ++t) {
    const int x = random() % w, y = random() % h;
    const double lon = gt[0] + (x + 0.5) * gt[1], lat = gt[3] + (y + 0.5) * gt[5];
    const grid::Code code = grid::lonlat_to_code(lon, lat, level);
    const auto s = static_cast<std::size_t>(ref.labels.site[code]);
    mismatches += fid[std::size_t(y) * w + x] != double(ref.sites.table.sites[s].fid);
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(QtmvoronoiCli, OtChoosesTheBandTypeAndRefusesValuesItCannotHold) {
  const std::string dir = test_dir();
  const int level = 5;
  const Reference ref = reference(kCentres, level, {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"});
  // The default: Float32 (the FIDs are small); -ot Int32: the same FIDs, distances rounded.
  for (const std::string type : {"", "Int32"}) {
    SCOPED_TRACE(type);
    const std::string dst = dir + "/ot" + type + ".tif";
    std::vector<std::string> args{"-q", "-level", std::to_string(level), "-device", "cpu", kCentres, dst};
    if (!type.empty()) args.insert(args.begin(), {"-ot", type});
    const Result r = run(concat(args, kCsvOptions));
    ASSERT_EQ(r.status, 0) << r.err;
    const auto ds = open(dst, GDAL_OF_RASTER);
    ASSERT_TRUE(ds);
    EXPECT_EQ(ds->GetRasterBand(1)->GetRasterDataType(), type.empty() ? GDT_Float32 : GDT_Int32);
    EXPECT_EQ(ds->GetRasterBand(3)->GetNoDataValue(), -1.0);
    const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
    std::vector<double> fid(std::size_t(w) * h), metres(fid.size());
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, fid.data(), w, h, GDT_Float64, 0, 0), CE_None);
    ASSERT_EQ(ds->GetRasterBand(3)->RasterIO(GF_Read, 0, 0, w, h, metres.data(), w, h, GDT_Float64, 0, 0), CE_None);
    const int n = 1 << level;
    std::uint64_t mismatches = 0;
    for (int y = 0; y < h; ++y) {
      const int o = y / n, i = y % n;
      for (int j = 0; j <= 2 * i; ++j) {
        const grid::Code code = grid::Code(o) * n * n + grid::Code(i) * i + j;
        const std::size_t p = std::size_t(y) * w + j;
        const double d = ref.labels.distance_m[code];
        mismatches += fid[p] != double(ref.sites.table.sites[std::size_t(ref.labels.site[code])].fid) ||
                      metres[p] != (type.empty() ? d : std::nearbyint(d));
      }
    }
    EXPECT_EQ(mismatches, 0u);
  }
  // UInt16 holds the FIDs, not the distances of up to thousands of kilometres: a failure naming
  // -ot, found while writing, and nothing left.
  const std::string dst = dir + "/uint16.tif";
  const Result r = run(concat({"-ot", "UInt16", "-level", "4", "-device", "cpu", kCentres, dst}, kCsvOptions));
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find(dst + ": band 3 (distance_m): cell "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("outside UInt16 (0..65534, 65535 being nodata; distances are rounded to whole metres): "
                       "choose a wider -ot"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dst));
  EXPECT_TRUE(hidden_entries(dir).empty());
  // Vector output has no band type.
  const Result v = run(concat({"-ot", "Int32", "-level", "2", kCentres, dir + "/v.gpkg"}, kCsvOptions));
  EXPECT_EQ(v.status, 1) << v.err;
  EXPECT_NE(v.err.find("-ot is for raster output"), std::string::npos) << v.err;
}

// -bands: an allocation raster (the FID band alone) holds band 1 of the full raster, as Int32,
// and -threads changes no byte of either.
TEST(QtmvoronoiCli, BandsWriteTheBandsAskedForAndThreadsChangeNoByte) {
  const std::string dir = test_dir();
  const std::vector<std::string> common =
      concat({"-q", "-level", "8", "-device", "cpu", "-tr", "0.1", "0.1"}, kCsvOptions);  // 8 strips of 256 rows
  const auto bytes_of = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const std::string full = dir + "/full.tif", fid = dir + "/fid.tif";
  ASSERT_EQ(run(concat(common, {kCentres, full})).status, 0);
  for (const char* threads : {"1", "2", "5"}) {
    SCOPED_TRACE(std::string("-threads ") + threads);
    const std::string again = dir + "/full" + threads + ".tif", fid_again = dir + "/fid" + threads + ".tif";
    const Result r = run(concat(common, {"-threads", threads, kCentres, again}));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(bytes_of(again), bytes_of(full));
    const Result f = run(concat(common, {"-threads", threads, "-bands", "fid", kCentres, fid_again}));
    ASSERT_EQ(f.status, 0) << f.err;
    if (std::string(threads) == "1") {
      fs::copy_file(fid_again, fid);
    } else {
      EXPECT_EQ(bytes_of(fid_again), bytes_of(fid));
    }
  }
  const auto a = open(full, GDAL_OF_RASTER), b = open(fid, GDAL_OF_RASTER);
  ASSERT_TRUE(a && b);
  ASSERT_EQ(b->GetRasterCount(), 1);
  EXPECT_EQ(b->GetRasterBand(1)->GetRasterDataType(), GDT_Int32);
  EXPECT_STREQ(b->GetRasterBand(1)->GetDescription(), "site_fid");
  const int w = a->GetRasterXSize(), h = a->GetRasterYSize();
  std::vector<double> va(std::size_t(w) * h), vb(va.size());
  ASSERT_EQ(a->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, va.data(), w, h, GDT_Float64, 0, 0), CE_None);
  ASSERT_EQ(b->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, vb.data(), w, h, GDT_Float64, 0, 0), CE_None);
  EXPECT_TRUE(va == vb);
}

TEST(QtmvoronoiCli, ShapefileSidecarsMoveTogether) {
  const std::string dir = test_dir();
  const Result r = run(concat({"-q", "-level", "4", "-layers", "regions", kCentres, dir + "/regions.shp"}, kCsvOptions));
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* ext : {".shp", ".shx", ".dbf", ".prj"}) EXPECT_TRUE(fs::exists(dir + "/regions" + ext)) << ext;
  EXPECT_TRUE(hidden_entries(dir).empty());
  const auto ds = open(dir + "/regions.shp", GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  EXPECT_GT(ds->GetLayer(0)->GetFeatureCount(), 200);
  // One .shp file holds one layer: refused before any work, nothing written beside it.
  const Result three = run(concat({"-q", "-level", "4", kCentres, dir + "/three.shp"}, kCsvOptions));
  EXPECT_EQ(three.status, 1);
  EXPECT_NE(three.err.find("-layers"), std::string::npos) << three.err;
  EXPECT_FALSE(fs::exists(dir + "/boundary_cells.shp"));
  EXPECT_FALSE(fs::exists(dir + "/three.shp"));
  // A directory destination holds a shapefile per layer, and moves as one.
  const Result folder = run(concat({"-q", "-level", "4", "-of", "ESRI Shapefile", kCentres, dir + "/layers"}, kCsvOptions));
  ASSERT_EQ(folder.status, 0) << folder.err;
  for (const char* name : {"regions.shp", "boundary_cells.shp", "voronoi_edges.shp"}) {
    EXPECT_TRUE(fs::exists(dir + "/layers/" + name)) << name;
  }
  EXPECT_TRUE(hidden_entries(dir).empty());
}

// ---------------------------------------------------------------------------------------------
// Failures leave nothing behind

TEST(QtmvoronoiCli, SingleLayerFilesAndCsv) {
  const std::string dir = test_dir();
  // GeoJSON holds one layer: refused before any work, nothing written.
  const Result json = run(concat({"-level", "3", kCentres, dir + "/r.geojson"}, kCsvOptions));
  EXPECT_EQ(json.status, 1);
  EXPECT_NE(json.err.find("a GeoJSON file holds one layer"), std::string::npos) << json.err;
  EXPECT_FALSE(fs::exists(dir + "/r.geojson"));
  EXPECT_TRUE(hidden_entries(dir).empty());
  // CSV output keeps the geometry, as WKT.
  const Result csv = run(concat({"-q", "-level", "3", "-layers", "regions", kCentres, dir + "/r.csv"}, kCsvOptions));
  ASSERT_EQ(csv.status, 0) << csv.err;
  EXPECT_EQ(read_all(dir + "/r.csv").rfind("WKT,", 0), 0u);
  // A CSV source read without the open options that name its coordinates: say how.
  const Result bare = run({"-level", "3", kCentres, dir + "/bare.gpkg"});
  EXPECT_EQ(bare.status, 1);
  EXPECT_NE(bare.err.find("-oo X_POSSIBLE_NAMES"), std::string::npos) << bare.err;
}

TEST(QtmvoronoiCli, SitesWithoutACellAreReportedOnceAfterLabelling) {
  // At level 3 (512 cells) many of the 241 country centres win no cell: one warning, with the
  // count after labelling, and every site keeps its row.
  const std::string dir = test_dir();
  const std::string dst = dir + "/few.gpkg";
  const Result r = run(concat({"-level", "3", "-layers", "regions", kCentres, dst}, kCsvOptions));
  ASSERT_EQ(r.status, 0) << r.err;
  std::size_t warnings = 0;
  for (std::size_t at = r.err.find("no cell of their own"); at != std::string::npos;
       at = r.err.find("no cell of their own", at + 1)) {
    ++warnings;
  }
  EXPECT_EQ(warnings, 1u) << r.err;
  EXPECT_NE(r.err.find("got no cell of their own at level 3"), std::string::npos) << r.err;
  const auto ds = open(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), 241);
}

TEST(QtmvoronoiCli, OverwriteSemantics) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/out.gpkg";
  const auto base = concat({"-q", "-layers", "regions"}, kCsvOptions);
  ASSERT_EQ(run(concat({"-level", "3", kCentres, dst}, base)).status, 0);
  const std::string first = read_all(dst);

  // Exists: refused before any work (a missing source is not even looked at).
  const Result again = run(concat({"-level", "4", kTestdata + "/no_such.csv", dst}, base));
  EXPECT_EQ(again.status, 1);
  EXPECT_NE(again.err.find("exists"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find("-overwrite"), std::string::npos) << again.err;
  EXPECT_EQ(read_all(dst), first);

  // -overwrite with a failing run: still untouched.
  const Result failing = run(concat({"-overwrite", "-level", "4", "-where", "no_such_field = 1", kCentres, dst}, base));
  EXPECT_EQ(failing.status, 1);
  EXPECT_EQ(read_all(dst), first);

  // -overwrite: replaced.
  ASSERT_EQ(run(concat({"-overwrite", "-level", "4", kCentres, dst}, base)).status, 0);
  const auto ds = open(dst, GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  std::uint64_t cells = 0;
  for (auto& f : *ds->GetLayerByName("regions")) cells += f->GetFieldAsInteger64("cells");
  EXPECT_EQ(cells, grid::cell_count(4));
  EXPECT_TRUE(hidden_entries(dir).empty());
}

TEST(QtmvoronoiCli, BadSourceNamesTheFile) {
  const std::string dir = test_dir();
  const std::string src = dir + "/missing.gpkg";
  const Result r = run({src, dir + "/out.gpkg"});
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(src), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("Usage:"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out.gpkg"));
  EXPECT_TRUE(hidden_entries(dir).empty());
}

TEST(QtmvoronoiCli, UnwritableDirectoryFailsClearly) {
  const std::string dir = test_dir();
  // Root ignores permission bits; /proc refuses new files to everyone.
  std::string locked = dir + "/locked";
  if (geteuid() == 0) {
    locked = "/proc";
  } else {
    fs::create_directory(locked);
    chmod(locked.c_str(), 0555);
  }
  const Result r = run(concat({"-level", "3", kCentres, locked + "/out.gpkg"}, kCsvOptions));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("cannot write '" + locked + "/out.gpkg'"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(locked + "/out.gpkg"));

  const Result missing = run(concat({"-level", "3", kCentres, dir + "/no/such/dir/out.gpkg"}, kCsvOptions));
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.err.find("no directory"), std::string::npos) << missing.err;
  if (geteuid() != 0) chmod(locked.c_str(), 0755);
}

TEST(QtmvoronoiCli, OptionsThatDoNotSuitTheFormatOrTheHost) {
  const std::string dir = test_dir();
  const Result co = run(concat({"-co", "COMPRESS=LZW", kCentres, dir + "/a.gpkg"}, kCsvOptions));
  EXPECT_EQ(co.status, 1);
  EXPECT_NE(co.err.find("-co"), std::string::npos) << co.err;
  const Result memory = run(concat({"-level", "24", kCentres, dir + "/b.gpkg"}, kCsvOptions));
  EXPECT_EQ(memory.status, 1);
  EXPECT_NE(memory.err.find("needs about"), std::string::npos) << memory.err;
  const Result vertices = run(concat({"-vertices", "all", kCentres, dir + "/v.tif"}, kCsvOptions));
  EXPECT_EQ(vertices.status, 1);
  EXPECT_NE(vertices.err.find("-vertices"), std::string::npos) << vertices.err;
  const Result guess = run(concat({kCentres, dir + "/c.unknownext"}, kCsvOptions));
  EXPECT_EQ(guess.status, 1);
  EXPECT_NE(guess.err.find("-of"), std::string::npos) << guess.err;
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(QtmvoronoiCli, ProgressOnStderr) {
  const std::string dir = test_dir();
  const Result r = run(concat({"-progress", "-level", "3", "-layers", "regions", kCentres, dir + "/p.gpkg"}, kCsvOptions));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
  // Warnings may break the bar's line: take it without the message lines.
  std::string bar;
  std::istringstream lines(r.err);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("qtmvoronoi:", 0) != 0) bar += line;
  }
  EXPECT_EQ(bar, "0...10...20...30...40...50...60...70...80...90...100 - done.") << r.err;
  const Result q = run(concat({"-q", "-progress", "-level", "3", "-layers", "regions", kCentres, dir + "/q.gpkg"},
                              kCsvOptions));
  ASSERT_EQ(q.status, 0) << q.err;
  EXPECT_EQ(q.err.find("0..."), std::string::npos) << q.err;
}

TEST(QtmvoronoiCli, SigtermWhileWritingLeavesNothing) {
  qtmv::test::expect_clean_stop_while_writing(concat({kCentres}, kCsvOptions), SIGTERM, "SIGTERM", 3.0);
}

// ---------------------------------------------------------------------------------------------
// The library entry point

TEST(QtmvoronoiLibrary, RunsIntoVsimemWithProgressAndMessages) {
  qtmv::VoronoiOptions options;
  options.level = 4;
  options.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  options.device = "cpu";
  options.vector.layers = {"regions"};
  double last = -1;
  bool monotonic = true;
  options.progress = [&](double f, const char*) {
    monotonic = monotonic && f >= last;
    last = f;
    return true;
  };
  std::vector<std::string> info;
  options.messages = [&](qtmv::Severity s, const std::string& m) {
    if (s == qtmv::Severity::info) info.push_back(m);
  };
  const std::string dst = "/vsimem/qtmvoronoi_library_test.gpkg";
  const qtmv::VoronoiSummary summary = qtmv::run_voronoi(kCentres, dst, options);
  EXPECT_EQ(summary.driver, "GPKG");
  EXPECT_FALSE(summary.raster);
  EXPECT_EQ(summary.level, 4);
  EXPECT_EQ(summary.cells, grid::cell_count(4));
  EXPECT_GT(summary.sites, 200u);
  EXPECT_TRUE(monotonic);
  EXPECT_DOUBLE_EQ(last, 1.0);
  ASSERT_FALSE(info.empty());
  EXPECT_EQ(info.back(), summary.line());
  {
    const auto ds = open(dst, GDAL_OF_VECTOR);
    ASSERT_TRUE(ds);
    EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), static_cast<GIntBig>(summary.sites));
  }
  // Exists now: refused without overwrite, replaced with it.
  EXPECT_THROW(qtmv::run_voronoi(kCentres, dst, options), qtmv::VoronoiError);
  options.overwrite = true;
  EXPECT_NO_THROW(qtmv::run_voronoi(kCentres, dst, options));
  // A stop asked for by the progress callback is an Interrupted, and leaves no file.
  const std::string stopped = "/vsimem/qtmvoronoi_stopped.gpkg";
  options.progress = [](double f, const char*) { return f < 0.5; };
  EXPECT_THROW(qtmv::run_voronoi(kCentres, stopped, options), qtmv::Interrupted);
  VSIStatBufL stat;
  EXPECT_NE(VSIStatL(stopped.c_str(), &stat), 0);
  // Stopped while writing directly into /vsimem/: what the driver made is removed.
  options.progress = [](double f, const char*) { return f < 0.9; };
  EXPECT_THROW(qtmv::run_voronoi(kCentres, stopped, options), qtmv::Interrupted);
  EXPECT_NE(VSIStatL(stopped.c_str(), &stat), 0);
  // Stopped while overwriting it in place: the old dataset is put back, whole.
  const GIntBig rows = open(dst, GDAL_OF_VECTOR)->GetLayerByName("regions")->GetFeatureCount();
  EXPECT_THROW(qtmv::run_voronoi(kCentres, dst, options), qtmv::Interrupted);
  {
    const auto ds = open(dst, GDAL_OF_VECTOR);
    ASSERT_TRUE(ds);
    EXPECT_EQ(ds->GetLayerByName("regions")->GetFeatureCount(), rows);
  }
  VSIUnlink(dst.c_str());
}

/// SQLite's page size of a GeoPackage (bytes).
long long sqlite_page_size_of(const std::string& path) {
  const auto ds = open(path, GDAL_OF_VECTOR);
  if (!ds) return -1;
  OGRLayer* result = ds->ExecuteSQL("PRAGMA page_size", nullptr, nullptr);
  if (!result) return -1;
  const OGRFeatureUniquePtr row(result->GetNextFeature());
  const long long size = row ? row->GetFieldAsInteger64(0) : -1;
  ds->ReleaseResultSet(result);
  return size;
}

/// Same FID, field values and geometry (as WKB) of two features of different datasets.
bool same_row(OGRFeature& a, OGRFeature& b) {
  if (a.GetFID() != b.GetFID() || a.GetFieldCount() != b.GetFieldCount()) return false;
  for (int f = 0; f < a.GetFieldCount(); ++f) {
    if (std::string(a.GetFieldAsString(f)) != b.GetFieldAsString(f)) return false;
  }
  const OGRGeometry* ga = a.GetGeometryRef();
  const OGRGeometry* gb = b.GetGeometryRef();
  if (!ga || !gb) return !ga && !gb;
  std::vector<unsigned char> wa(ga->WkbSize()), wb(gb->WkbSize());
  ga->exportToWkb(wkbNDR, wa.data(), wkbVariantIso);
  gb->exportToWkb(wkbNDR, wb.data(), wkbVariantIso);
  return wa == wb;
}

TEST(QtmvoronoiLibrary, LargeGeoPackagesGetSqlitesLargestPagesAndTheSameRows) {
  const std::string dir = test_dir();
  qtmv::VoronoiOptions options;
  options.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
  options.device = "cpu";
  options.vector.layers = {"cells", "regions"};
  // Level 7's cells layer is about 20 MB, level 8's 79 MB: past write::kLargeSqliteFileBytes.
  options.level = 7;
  qtmv::run_voronoi(kCentres, dir + "/small.gpkg", options);
  EXPECT_EQ(sqlite_page_size_of(dir + "/small.gpkg"), 4096);
  options.level = 8;
  qtmv::run_voronoi(kCentres, dir + "/large.gpkg", options);
  EXPECT_EQ(sqlite_page_size_of(dir + "/large.gpkg"), 65536);
  {
    // The user's own pragmas win.
    const CPLConfigOptionSetter user("OGR_SQLITE_PRAGMA", "page_size=4096", false);
    qtmv::run_voronoi(kCentres, dir + "/user.gpkg", options);
  }
  EXPECT_EQ(sqlite_page_size_of(dir + "/user.gpkg"), 4096);
  const auto large = open(dir + "/large.gpkg", GDAL_OF_VECTOR), user = open(dir + "/user.gpkg", GDAL_OF_VECTOR);
  ASSERT_TRUE(large && user);
  for (const char* name : {"cells", "regions"}) {
    SCOPED_TRACE(name);
    OGRLayer* a = large->GetLayerByName(name);
    OGRLayer* b = user->GetLayerByName(name);
    ASSERT_TRUE(a && b);
    ASSERT_EQ(a->GetFeatureCount(), b->GetFeatureCount());
    EXPECT_GT(a->GetFeatureCount(), 200);
    std::int64_t different = 0;
    for (;;) {
      const OGRFeatureUniquePtr fa(a->GetNextFeature()), fb(b->GetNextFeature());
      if (!fa || !fb) {
        EXPECT_EQ(!fa, !fb);
        break;
      }
      if (!same_row(*fa, *fb)) ++different;
    }
    EXPECT_EQ(different, 0);
  }
}

TEST(QtmvoronoiLibrary, RasterUnderASmallMemoryLimitIsWrittenInManyStripsAndEqualsTheWholeRun) {
  for (const auto layout : {qtmv::write::RasterOptions::Layout::qtm, qtmv::write::RasterOptions::Layout::lonlat}) {
    const bool qtm = layout == qtmv::write::RasterOptions::Layout::qtm;
    SCOPED_TRACE(qtm ? "qtm" : "lonlat");
    qtmv::VoronoiOptions options;
    options.level = 6;
    options.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
    options.device = "cpu";
    options.raster.layout = layout;
    const std::string whole = std::string("/vsimem/qtmv_whole_") + (qtm ? "qtm" : "lonlat") + ".tif";
    const std::string strips = std::string("/vsimem/qtmv_strips_") + (qtm ? "qtm" : "lonlat") + ".tif";
    const qtmv::VoronoiSummary a = qtmv::run_voronoi(kCentres, whole, options);
    EXPECT_TRUE(a.raster);
    // 1 MiB for the whole run: strips of 256 KiB, and progress reported after each.
    options.memory_limit_bytes = 1 << 20;
    int reports = 0;
    options.progress = [&](double, const char* stage) {
      reports += std::string(stage) == "write";
      return true;
    };
    const qtmv::VoronoiSummary b = qtmv::run_voronoi(kCentres, strips, options);
    EXPECT_GT(reports, 10);
    EXPECT_EQ(a.sites_without_cell, b.sites_without_cell);
    const auto da = open(whole, GDAL_OF_RASTER), db = open(strips, GDAL_OF_RASTER);
    ASSERT_TRUE(da && db);
    const int w = da->GetRasterXSize(), h = da->GetRasterYSize();
    ASSERT_EQ(db->GetRasterXSize(), w);
    ASSERT_EQ(db->GetRasterYSize(), h);
    for (int band = 1; band <= 3; ++band) {
      std::vector<double> va(std::size_t(w) * h), vb(va.size());
      ASSERT_EQ(da->GetRasterBand(band)->RasterIO(GF_Read, 0, 0, w, h, va.data(), w, h, GDT_Float64, 0, 0), CE_None);
      ASSERT_EQ(db->GetRasterBand(band)->RasterIO(GF_Read, 0, 0, w, h, vb.data(), w, h, GDT_Float64, 0, 0), CE_None);
      EXPECT_TRUE(va == vb) << "band " << band;
    }
    VSIUnlink(whole.c_str());
    VSIUnlink(strips.c_str());
    // Too little for even the strips and the tree: refused before any work, saying what for.
    options.memory_limit_bytes = 100000;
    try {
      qtmv::run_voronoi(kCentres, strips, options);
      ADD_FAILURE() << "no refusal";
    } catch (const qtmv::VoronoiError& e) {
      EXPECT_NE(std::string(e.what()).find("level 6 needs about "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("for the labeller's tree and the raster's strips"), std::string::npos)
          << e.what();
    }
    VSIStatBufL stat;
    EXPECT_NE(VSIStatL(strips.c_str(), &stat), 0);
  }
}

TEST(QtmvoronoiLibrary, RasterStoppedMidStreamLeavesNothing) {
  const std::string dir = test_dir();
  for (const char* format : {"GTiff", "COG"}) {
    SCOPED_TRACE(format);
    qtmv::VoronoiOptions options;
    options.level = 7;
    options.read.open_options = {"X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"};
    options.device = "cpu";
    options.format = format;
    options.memory_limit_bytes = 4 << 20;  // many strips
    bool writing = false;
    options.progress = [&](double, const char* stage) {
      if (std::string(stage) == "write") {
        if (writing) return false;  // the second strip's report: stop
        writing = true;
      }
      return true;
    };
    const std::string dst = dir + "/stopped_" + format + ".tif";
    EXPECT_THROW(qtmv::run_voronoi(kCentres, dst, options), qtmv::Interrupted);
    EXPECT_TRUE(writing);
    EXPECT_FALSE(fs::exists(dst));
    EXPECT_TRUE(hidden_entries(dir).empty());
    EXPECT_TRUE(fs::is_empty(dir)) << dir;
  }
}

}  // namespace

namespace {

/// A GeoPackage of the country centres (points, "towns"), ten countries (polygons, "areas") and
/// both in one layer ("merged", towns then areas, each with the FID it has in its own layer).
std::string composite_source(const std::string& dir) {
  const std::string path = dir + "/composite.gpkg";
  GDALAllRegister();
  GDALDatasetUniquePtr centres = open(kCentres, GDAL_OF_VECTOR);
  char* csv_options[] = {const_cast<char*>("X_POSSIBLE_NAMES=lon"), const_cast<char*>("Y_POSSIBLE_NAMES=lat"), nullptr};
  centres.reset(GDALDataset::Open(kCentres.c_str(), GDAL_OF_VECTOR, nullptr, csv_options));
  GDALDatasetUniquePtr countries = open(kCountries, GDAL_OF_VECTOR);
  GDALDriver* gpkg = GetGDALDriverManager()->GetDriverByName("GPKG");
  GDALDatasetUniquePtr out(gpkg->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  OGRSpatialReference wgs84;
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRLayer* towns = out->CreateLayer("towns", &wgs84, wkbPoint);
  OGRLayer* areas = out->CreateLayer("areas", &wgs84, wkbMultiPolygon);
  OGRLayer* merged = out->CreateLayer("merged", &wgs84, wkbUnknown);
  OGRFieldDefn name("name", OFTString);
  for (OGRLayer* l : {towns, areas, merged}) l->CreateField(&name);
  const auto copy = [&](OGRLayer* from, OGRLayer* to, int count, const char* name_field) {
    int n = 0;
    for (auto& f : *from) {
      if (n++ == count) break;
      for (OGRLayer* target : {to, merged}) {
        OGRFeatureUniquePtr g(OGRFeature::CreateFeature(target->GetLayerDefn()));
        g->SetField("name", f->GetFieldAsString(name_field));
        g->SetGeometry(f->GetGeometryRef());
        EXPECT_EQ(target->CreateFeature(g.get()), OGRERR_NONE);
      }
    }
  };
  copy(centres->GetLayer(0), towns, 60, "name");
  copy(countries->GetLayerByName("countries_110m"), areas, 10, "name");
  return path;
}

/// The regions' rows (cells, area, geometry as WKT) in FID order.
std::vector<std::string> region_rows(const std::string& path) {
  std::vector<std::string> rows;
  GDALDatasetUniquePtr ds = open(path, GDAL_OF_VECTOR);
  if (!ds) return rows;
  for (auto& f : *ds->GetLayerByName("regions")) {
    // (Each value copied at once: OGR reuses one buffer for a feature's numbers as text.)
    std::ostringstream row;
    row.precision(17);
    row << f->GetFieldAsString("name") << " " << f->GetFieldAsInteger64("cells") << " " << f->GetFieldAsDouble("area_m2")
        << " " << f->GetGeometryRef()->exportToWkt();
    rows.push_back(row.str());
  }
  return rows;
}

}  // namespace

TEST(QtmvoronoiCli, CompositeSitesFromSeveralLayersLabelAsOneMergedLayer) {
  const std::string dir = test_dir();
  const std::string source = composite_source(dir);
  const Result composite = run({"-level", "7", "-l", "towns", "-l", "areas", "-layers", "regions,voronoi_edges,boundary_cells",
                                source, dir + "/composite_out.gpkg"});
  ASSERT_EQ(composite.status, 0) << composite.err;
  const Result merged = run({"-level", "7", "-l", "merged", "-layers", "regions", source, dir + "/merged_out.gpkg"});
  ASSERT_EQ(merged.status, 0) << merged.err;
  // The same sites in the same order: the same regions, row by row.
  const std::vector<std::string> a = region_rows(dir + "/composite_out.gpkg");
  ASSERT_EQ(a.size(), 70u);
  EXPECT_EQ(a, region_rows(dir + "/merged_out.gpkg"));

  // Each row names its site's layer and keeps the FID of that layer.
  GDALDatasetUniquePtr ds = open(dir + "/composite_out.gpkg", GDAL_OF_VECTOR);
  ASSERT_TRUE(ds);
  int row = 0;
  for (auto& f : *ds->GetLayerByName("regions")) {
    const bool town = row < 60;
    EXPECT_STREQ(f->GetFieldAsString("site_layer"), town ? "towns" : "areas") << row;
    EXPECT_EQ(f->GetFieldAsInteger64("site_fid"), town ? row + 1 : row - 60 + 1) << row;
    ++row;
  }
  int mixed = 0;
  for (auto& f : *ds->GetLayerByName("voronoi_edges")) {
    mixed += std::string(f->GetFieldAsString("layer_a")) != f->GetFieldAsString("layer_b");
  }
  EXPECT_GT(mixed, 0) << "no edge between a town and an area";
  std::set<std::string> boundary_layers;
  for (auto& f : *ds->GetLayerByName("boundary_cells")) boundary_layers.insert(f->GetFieldAsString("site_layer"));
  EXPECT_EQ(boundary_layers, (std::set<std::string>{"areas", "towns"}));

  // Bad input as for one layer; a raster cannot tell the layers apart.
  const Result missing = run({"-l", "towns", "-l", "nope", source, dir + "/x.gpkg"});
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.err.find("has no layer 'nope'"), std::string::npos) << missing.err;
  EXPECT_EQ(run({"-l", "towns", "-l", "towns", source, dir + "/x.gpkg"}).status, 2);
  const Result raster = run({"-level", "6", "-l", "towns", "-l", "areas", source, dir + "/x.tif"});
  EXPECT_EQ(raster.status, 1);
  EXPECT_NE(raster.err.find("-l names 2 layers"), std::string::npos) << raster.err;
  EXPECT_FALSE(fs::exists(dir + "/x.gpkg"));
  EXPECT_FALSE(fs::exists(dir + "/x.tif"));
}
