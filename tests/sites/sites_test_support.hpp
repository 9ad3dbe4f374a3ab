// Helpers for the readers' tests: datasets made through the GDAL API, options that collect
// messages, GEOS references.
#pragma once

#include <gtest/gtest.h>

#include "../test_temp_dir.hpp"

#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogr_api.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "grid/qtm.hpp"
#include "sites/ogr_site_reader.hpp"

namespace qtmv::sites::test {

/// A feature to write: geometry as WKT (empty: no geometry) and a name field.
struct TestFeature {
  std::string wkt;
  std::string name;
  std::shared_ptr<OGRGeometry> geometry = nullptr;  ///< used instead of wkt when set (NaN coordinates)
};

/// A fresh path in the test process's temporary directory (removed when the tests end).
inline std::string temp_path(const std::string& name) {
  static int counter = 0;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string path = qtmv::test::process_temp_dir() + "/" + info->test_suite_name() + "_" + info->name() + "_" +
                           std::to_string(counter++) + "_" + name;
  VSIUnlink(path.c_str());
  for (const char* ext : {".shp", ".shx", ".dbf", ".prj", ".cpg"}) VSIUnlink((path + ext).c_str());
  return path;
}

/// Writes a one-layer dataset. srs: any SetFromUserInput text, or empty for a layer without CRS.
inline std::string make_dataset(const std::string& path, const std::string& driver_name, const std::string& layer_name,
                                const std::string& srs_text, const std::vector<TestFeature>& features) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(driver_name.c_str());
  if (!driver) throw std::runtime_error("no GDAL driver " + driver_name);
  GDALDatasetUniquePtr ds(driver->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  if (!ds) throw std::runtime_error("cannot create " + path);
  std::unique_ptr<OGRSpatialReference> srs;
  if (!srs_text.empty()) {
    srs = std::make_unique<OGRSpatialReference>();
    srs->SetFromUserInput(srs_text.c_str());
    srs->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }
  OGRLayer* layer = ds->CreateLayer(layer_name.c_str(), srs.get(), wkbUnknown, nullptr);
  if (!layer) throw std::runtime_error("cannot create layer " + layer_name + " in " + path);
  OGRFieldDefn field("name", OFTString);
  layer->CreateField(&field);
  for (const TestFeature& f : features) {
    OGRFeatureUniquePtr feature(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    feature->SetField("name", f.name.c_str());
    if (f.geometry) {
      feature->SetGeometry(f.geometry.get());
    } else if (!f.wkt.empty()) {
      OGRGeometry* geometry = nullptr;
      if (OGRGeometryFactory::createFromWkt(f.wkt.c_str(), nullptr, &geometry) != OGRERR_NONE) {
        throw std::runtime_error("bad WKT " + f.wkt);
      }
      feature->SetGeometryDirectly(geometry);
    }
    if (layer->CreateFeature(feature.get()) != OGRERR_NONE) throw std::runtime_error("cannot write " + f.wkt);
  }
  return path;
}

/// Overwrites the geometry blob of feature `fid` of a GeoPackage's first layer with one that
/// has a valid header and broken WKB: GDAL fails on that feature only.
inline void corrupt_geometry(const std::string& path, GIntBig fid) {
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_UPDATE));
  if (!ds) throw std::runtime_error("cannot update " + path);
  const std::string table = ds->GetLayer(0)->GetName(), column = ds->GetLayer(0)->GetGeometryColumn();
  // The R-tree triggers would reject the broken blob: drop them first.
  std::vector<std::string> triggers;
  OGRLayer* list = ds->ExecuteSQL("SELECT name FROM sqlite_master WHERE type = 'trigger'", nullptr, nullptr);
  if (!list) throw std::runtime_error("cannot list the triggers of " + path);
  for (auto& f : *list) triggers.push_back(f->GetFieldAsString(0));
  ds->ReleaseResultSet(list);
  for (const auto& t : triggers) ds->ExecuteSQL(("DROP TRIGGER \"" + t + "\"").c_str(), nullptr, nullptr);
  ds->ExecuteSQL(("UPDATE \"" + table + "\" SET \"" + column + "\" = X'47500001E6100000DEADBEEF' WHERE fid = " +
                  std::to_string(fid)).c_str(),
                 nullptr, nullptr);
}

/// A CRS from any SetFromUserInput text, in lon/lat (traditional GIS) order.
inline OGRSpatialReference srs_of(const char* text) {
  OGRSpatialReference srs;
  srs.SetFromUserInput(text);
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

/// Options at a level whose messages are kept in `messages`.
inline ReadOptions options_at(int level, std::vector<std::string>* messages) {
  ReadOptions o;
  o.level = level;
  if (messages) o.messages = [messages](Severity, const std::string& m) { messages->push_back(m); };
  return o;
}

inline bool any_contains(const std::vector<std::string>& messages, const std::string& part) {
  return std::any_of(messages.begin(), messages.end(), [&](const std::string& m) { return m.find(part) != std::string::npos; });
}

/// Distinct site-cell codes per site.
inline std::vector<std::set<grid::Code>> site_cells_by_site(const SiteGeometry& g) {
  std::vector<std::set<grid::Code>> out(g.site_count);
  for (const auto& c : g.site_cells) out[c.site].insert(c.code);
  return out;
}

/// Fixed-cell codes per site.
/// Per site, the cells it claims: its fixed cells and the cells of its fixed nodes.
inline std::vector<std::set<grid::Code>> fixed_cells_by_site(const SiteGeometry& g) {
  std::vector<std::set<grid::Code>> out(g.site_count);
  for (const auto& c : g.fixed_cells) out[c.site].insert(c.code);
  for (const auto& n : g.fixed_nodes) {
    const grid::Cell node = grid::cell_of(n.code, n.level);
    const int k = g.level - n.level;
    for (std::uint64_t r = 0; r < (std::uint64_t{1} << k); ++r) {
      const grid::RowCodes row = grid::row_codes_below(node, k, r, g.level);
      for (grid::Code code = row.first; code <= row.last; ++code) out[n.site].insert(code);
    }
  }
  return out;
}

/// Cells of a level whose centres GEOS puts inside (strictly) a polygon given as lon/lat WKT.
inline std::set<grid::Code> geos_inside(const OGRGeometry& polygon, int level) {
  std::set<grid::Code> out;
  OGREnvelope env;
  polygon.getEnvelope(&env);
  OGRPreparedGeometryH prepared = OGRCreatePreparedGeometry(OGRGeometry::ToHandle(const_cast<OGRGeometry*>(&polygon)));
  const grid::Code n = grid::cell_count(level);
  for (grid::Code code = 0; code < n; ++code) {
    const grid::LonLat c = grid::cell_centre(code, level);
    if (c.lon < env.MinX || c.lon > env.MaxX || c.lat < env.MinY || c.lat > env.MaxY) continue;
    OGRPoint p(c.lon, c.lat);
    if (OGRPreparedGeometryContains(prepared, OGRGeometry::ToHandle(&p))) out.insert(code);
  }
  OGRDestroyPreparedGeometry(prepared);
  return out;
}

/// Expects two reads' geometries the same, every array element by element (the pieces' ends bit
/// for bit).
inline void expect_same_geometry(const SiteGeometry& a, const SiteGeometry& b) {
  ASSERT_EQ(a.site_count, b.site_count);
  ASSERT_EQ(a.pieces.size(), b.pieces.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < a.pieces.size(); ++k) {
    const SitePiece &p = a.pieces[k], &q = b.pieces[k];
    differ += p.site != q.site || std::memcmp(&p.a, &q.a, sizeof p.a) != 0 || std::memcmp(&p.b, &q.b, sizeof p.b) != 0;
  }
  EXPECT_EQ(differ, 0u) << "pieces differ";
  ASSERT_EQ(a.site_cells.size(), b.site_cells.size());
  differ = 0;
  for (std::size_t k = 0; k < a.site_cells.size(); ++k) {
    const SiteCell &p = a.site_cells[k], &q = b.site_cells[k];
    differ += p.code != q.code || p.site != q.site || p.piece_begin != q.piece_begin || p.piece_end != q.piece_end;
  }
  EXPECT_EQ(differ, 0u) << "site cells differ";
  ASSERT_EQ(a.fixed_cells.size(), b.fixed_cells.size());
  differ = 0;
  for (std::size_t k = 0; k < a.fixed_cells.size(); ++k) {
    differ += a.fixed_cells[k].code != b.fixed_cells[k].code || a.fixed_cells[k].site != b.fixed_cells[k].site;
  }
  EXPECT_EQ(differ, 0u) << "fixed cells differ";
  ASSERT_EQ(a.fixed_nodes.size(), b.fixed_nodes.size());
  differ = 0;
  for (std::size_t k = 0; k < a.fixed_nodes.size(); ++k) {
    const FixedNode &p = a.fixed_nodes[k], &q = b.fixed_nodes[k];
    differ += p.code != q.code || p.level != q.level || p.site != q.site;
  }
  EXPECT_EQ(differ, 0u) << "fixed nodes differ";
}

inline std::unique_ptr<OGRGeometry> from_wkt(const std::string& wkt) {
  OGRGeometry* g = nullptr;
  if (OGRGeometryFactory::createFromWkt(wkt.c_str(), nullptr, &g) != OGRERR_NONE) throw std::runtime_error("bad WKT " + wkt);
  return std::unique_ptr<OGRGeometry>(g);
}

}  // namespace qtmv::sites::test
