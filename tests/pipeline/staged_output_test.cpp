// The destination written all or nothing (pipeline/staged_output.hpp): what commit() moves in,
// what it moves aside and removes, and what it leaves: the user's other files, a file that
// appeared meanwhile (another run), the old dataset when a move fails.
#include "pipeline/staged_output.hpp"

#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <fstream>
#include <sstream>
#include <string>

#include "../test_temp_dir.hpp"
#include "pipeline/voronoi_error.hpp"

namespace qtmv::pipeline {
namespace {

std::string fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(test::process_temp_dir()) / ("staged_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The entries of `dir` whose names start with a dot (the staging directories).
int hidden_count(const std::string& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().filename().string().front() == '.';
  return n;
}

TEST(StagedOutput, AFileThatAppearedMeanwhileIsNeverReplaced) {
  const std::string dir = fresh_dir("appeared");
  const std::string dst = dir + "/out.csv";
  std::string message;
  {
    StagedOutput output(dst, /*overwrite=*/false);
    write_text(output.begin(), "ours");
    write_text(dir + "/out.csvt", "");  // not ours: a sidecar name, left as it is
    write_text(dst, "theirs");            // another run committed first
    try {
      output.commit();
    } catch (const VoronoiError& e) {
      message = e.what();
    }
  }
  EXPECT_EQ(message, "cannot write '" + dst + "': '" + dst + "' appeared while this run was writing (another run "
                     "writing the same destination?): it is left as it is, and this run's output is not kept");
  EXPECT_EQ(read_text(dst), "theirs");
  EXPECT_EQ(hidden_count(dir), 0);
}

TEST(StagedOutput, ASidecarMovedInIsTakenBackWhenTheNamedFileCannotFollow) {
  const std::string dir = fresh_dir("sidecar_back");
  const std::string dst = dir + "/out.shp";
  {
    StagedOutput output(dst, false);
    const fs::path made(output.begin());
    write_text(made, "shp");
    write_text(made.parent_path() / "out.dbf", "dbf");
    write_text(dst, "theirs");
    EXPECT_THROW(output.commit(), VoronoiError);
  }
  EXPECT_FALSE(fs::exists(dir + "/out.dbf"));  // ours went back, and away with the staging directory
  EXPECT_EQ(read_text(dst), "theirs");
  EXPECT_EQ(hidden_count(dir), 0);
}

TEST(StagedOutput, OverwriteRemovesTheOldDatasetsNamedSidecarsAndKeepsOtherFiles) {
  const std::string dir = fresh_dir("named_sidecars");
  const std::string dst = dir + "/out.gpkg";
  for (const char* name : {"out.gpkg", "out.gpkg-wal", "out.gpkg-shm", "out.gpkg.aux.xml"}) write_text(dir + "/" + name, "old");
  write_text(dir + "/out.txt", "notes");  // same stem, not the dataset's
  {
    StagedOutput output(dst, true);
    write_text(output.begin(), "new");
    output.commit();
  }
  EXPECT_EQ(read_text(dst), "new");
  for (const char* name : {"out.gpkg-wal", "out.gpkg-shm", "out.gpkg.aux.xml"}) {
    EXPECT_FALSE(fs::exists(dir + "/" + name)) << name;
  }
  EXPECT_EQ(read_text(dir + "/out.txt"), "notes");
  EXPECT_EQ(hidden_count(dir), 0);
}

TEST(StagedOutput, OverwriteRemovesTheFilesGdalListsForTheOldDataset) {
  if (GDALGetDriverCount() == 0) GDALAllRegister();
  const std::string dir = fresh_dir("gdal_list");
  const std::string dst = dir + "/out.shp";
  {
    // An old shapefile with a spatial index (out.qix), as ogrinfo's CREATE SPATIAL INDEX makes.
    GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("ESRI Shapefile");
    std::unique_ptr<GDALDataset> ds(driver->Create(dst.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    ASSERT_TRUE(ds);
    OGRLayer* layer = ds->CreateLayer("out", nullptr, wkbPoint, nullptr);
    OGRFeature feature(layer->GetLayerDefn());
    OGRPoint point(1, 2);
    feature.SetGeometry(&point);
    ASSERT_EQ(layer->CreateFeature(&feature), OGRERR_NONE);
    ds->ExecuteSQL("CREATE SPATIAL INDEX ON out", nullptr, nullptr);
  }
  ASSERT_TRUE(fs::exists(dir + "/out.qix"));
  write_text(dir + "/out.txt", "notes");
  {
    StagedOutput output(dst, true);
    const fs::path made(output.begin());
    write_text(made, "shp");
    write_text(made.parent_path() / "out.shx", "shx");
    write_text(made.parent_path() / "out.dbf", "dbf");
    output.commit();
  }
  EXPECT_FALSE(fs::exists(dir + "/out.qix"));
  EXPECT_EQ(read_text(dst), "shp");
  EXPECT_EQ(read_text(dir + "/out.dbf"), "dbf");
  EXPECT_EQ(read_text(dir + "/out.txt"), "notes");
  EXPECT_EQ(hidden_count(dir), 0);
}

TEST(StagedOutput, OverwriteIntoADirectoryOfLayersReplacesOnlyTheLayersWritten) {
  const std::string dir = fresh_dir("layer_directory");
  const std::string dst = dir + "/proj";
  fs::create_directory(dst);
  write_text(dst + "/notes.txt", "notes");
  write_text(dst + "/survey.geojson", "{}");
  write_text(dst + "/regions.csv", "old");
  write_text(dst + "/regions.csvt", "old types");  // the old layer's sidecar, if GDAL lists it
  {
    StagedOutput output(dst, true);
    const fs::path made(output.begin());
    fs::create_directory(made);
    write_text(made / "regions.csv", "new regions");
    write_text(made / "voronoi_edges.csv", "new edges");
    output.commit();
  }
  EXPECT_EQ(read_text(dst + "/notes.txt"), "notes");
  EXPECT_EQ(read_text(dst + "/survey.geojson"), "{}");
  EXPECT_EQ(read_text(dst + "/regions.csv"), "new regions");
  EXPECT_EQ(read_text(dst + "/voronoi_edges.csv"), "new edges");
  EXPECT_EQ(hidden_count(dir), 0);
  EXPECT_EQ(hidden_count(dst), 0);
}

TEST(StagedOutput, WithoutCommitNothingIsLeft) {
  const std::string dir = fresh_dir("no_commit");
  write_text(dir + "/out.tif", "old");
  {
    StagedOutput output(dir + "/out.tif", true);
    write_text(output.begin(), "half");
  }
  EXPECT_EQ(read_text(dir + "/out.tif"), "old");
  EXPECT_EQ(hidden_count(dir), 0);
}

}  // namespace
}  // namespace qtmv::pipeline
