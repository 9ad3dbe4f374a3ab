// The destination written all or nothing (pipeline/staged_output.hpp): what commit() moves in,
// what it moves aside and removes, and what it leaves: the user's other files, a file that
// appeared meanwhile (another run), the old dataset when a move fails.
#include "pipeline/staged_output.hpp"

#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

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

/// A file of GDAL's virtual file systems written whole.
void write_virtual(const std::string& path, const std::string& text) {
  VSILFILE* f = VSIFOpenL(path.c_str(), "wb");
  ASSERT_NE(f, nullptr) << path;
  VSIFWriteL(text.data(), 1, text.size(), f);
  VSIFCloseL(f);
}

/// A virtual file's text ("<none>" when it is not there).
std::string read_virtual(const std::string& path) {
  VSILFILE* f = VSIFOpenL(path.c_str(), "rb");
  if (!f) return "<none>";
  std::string text;
  char buffer[256];
  for (size_t n; (n = VSIFReadL(buffer, 1, sizeof buffer, f)) > 0;) text.append(buffer, n);
  VSIFCloseL(f);
  return text;
}

/// The names in a virtual directory, sorted.
std::vector<std::string> virtual_names(const std::string& dir) {
  std::vector<std::string> names;
  char** list = VSIReadDir(dir.c_str());
  for (char** name = list; name && *name; ++name) names.emplace_back(*name);
  CSLDestroy(list);
  std::sort(names.begin(), names.end());
  return names;
}

TEST(StagedOutput, AVirtualDestinationsOldDatasetSurvivesAFailedOverwrite) {
  const std::string dir = "/vsimem/staged_failed";
  write_virtual(dir + "/out.tif", "old");
  write_virtual(dir + "/out.tif.aux.xml", "old statistics");
  write_virtual(dir + "/notes.txt", "the user's");
  {
    StagedOutput output(dir + "/out.tif", /*overwrite=*/true);
    const std::string path = output.begin();
    EXPECT_EQ(path, dir + "/out.tif");
    EXPECT_EQ(read_virtual(path), "<none>");  // the old one is aside, not deleted
    write_virtual(path, "half");
    write_virtual(path + ".aux.xml", "half statistics");
  }  // no commit: the run failed
  EXPECT_EQ(read_virtual(dir + "/out.tif"), "old");
  EXPECT_EQ(read_virtual(dir + "/out.tif.aux.xml"), "old statistics");
  EXPECT_EQ(virtual_names(dir), (std::vector<std::string>{"notes.txt", "out.tif", "out.tif.aux.xml"}));
  VSIRmdirRecursive(dir.c_str());
}

TEST(StagedOutput, AVirtualDestinationsOverwriteReplacesTheWholeOldDataset) {
  const std::string dir = "/vsimem/staged_replaced";
  write_virtual(dir + "/out.tif", "old");
  write_virtual(dir + "/out.tif.aux.xml", "old statistics");
  write_virtual(dir + "/notes.txt", "the user's");
  {
    StagedOutput output(dir + "/out.tif", /*overwrite=*/true);
    write_virtual(output.begin(), "new");
    output.commit();
  }
  EXPECT_EQ(read_virtual(dir + "/out.tif"), "new");
  EXPECT_EQ(virtual_names(dir), (std::vector<std::string>{"notes.txt", "out.tif"}));
  VSIRmdirRecursive(dir.c_str());
}

TEST(StagedOutput, AVirtualFileSystemThatCannotRenameRefusesOverwriteAndKeepsTheOld) {
  const std::string zip = "/vsimem/staged_archive.zip";
  const std::string dst = "/vsizip/" + zip + "/out.csv";
  write_virtual(dst, "old");
  std::string message;
  {
    StagedOutput output(dst, /*overwrite=*/true);
    try {
      output.begin();
    } catch (const VoronoiError& e) {
      message = e.what();
    }
  }
  EXPECT_NE(message.find("cannot write '" + dst + "' with -overwrite: its file system cannot rename"),
            std::string::npos)
      << message;
  EXPECT_EQ(read_virtual(dst), "old");
  VSIUnlink(zip.c_str());
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
