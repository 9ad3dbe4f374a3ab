// Natural Earth countries (world-atlas 110m, public domain; testdata/world_atlas_countries_110m.*):
// at level 8 the fixed cells of every country are the cells whose centres GEOS puts inside it,
// and the countries as world-atlas writes them (crossing +-180 uncut) give the same cells as the
// same countries cut at +-180.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <vector>

#include "sites/ogr_site_reader.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

const std::string kCountries = std::string(QTMV_TESTDATA_DIR) + "/world_atlas_countries_110m.gpkg";
constexpr int kLevel = 8;

SiteSet read_layer(const std::string& layer, WrapMode wrap = WrapMode::automatic) {
  ReadOptions o = test::options_at(kLevel, nullptr);
  o.layers = {layer};
  o.wrap = wrap;
  return read_sites(kCountries, o);
}

/// GEOS's cells per country (the lowest id where two countries would claim a centre).
std::vector<std::set<grid::Code>> geos_cells_by_country(const std::string& layer_name, int count) {
  GDALDatasetUniquePtr ds(GDALDataset::Open(kCountries.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  OGRLayer* layer = ds->GetLayerByName(layer_name.c_str());
  std::vector<std::unique_ptr<OGRGeometry>> geometries;
  for (auto& f : *layer) geometries.emplace_back(f->StealGeometry());
  EXPECT_EQ(static_cast<int>(geometries.size()), count);
  std::vector<OGREnvelope> envelopes(geometries.size());
  std::vector<OGRPreparedGeometryH> prepared;
  for (std::size_t k = 0; k < geometries.size(); ++k) {
    geometries[k]->getEnvelope(&envelopes[k]);
    prepared.push_back(OGRCreatePreparedGeometry(OGRGeometry::ToHandle(geometries[k].get())));
  }
  std::vector<std::set<grid::Code>> out(geometries.size());
  for (grid::Code code = 0; code < grid::cell_count(kLevel); ++code) {
    const grid::LonLat c = grid::cell_centre(code, kLevel);
    OGRPoint p(c.lon, c.lat);
    for (std::size_t k = 0; k < geometries.size(); ++k) {
      const OGREnvelope& e = envelopes[k];
      if (c.lon < e.MinX || c.lon > e.MaxX || c.lat < e.MinY || c.lat > e.MaxY) continue;
      if (OGRPreparedGeometryContains(prepared[k], OGRGeometry::ToHandle(&p))) {
        out[k].insert(code);
        break;
      }
    }
  }
  for (auto h : prepared) OGRDestroyPreparedGeometry(h);
  return out;
}

std::string name_of(const SiteSet& set, int site) { return set.table.sites[site].attributes->GetFieldAsString("name"); }

TEST(NaturalEarth, FixedCellsOfEveryCountryEqualGeos) {
  const SiteSet set = read_layer("countries_110m_cut");
  ASSERT_EQ(set.geometry.site_count, 177);
  const auto fixed = test::fixed_cells_by_site(set.geometry);
  const auto geos = geos_cells_by_country("countries_110m_cut", 177);
  std::size_t total = 0;
  for (int s = 0; s < 177; ++s) {
    EXPECT_EQ(fixed[s], geos[s]) << name_of(set, s);
    total += fixed[s].size();
  }
  // Land is about 29% of the globe, Antarctica included.
  EXPECT_GT(total, grid::cell_count(kLevel) / 4);
  EXPECT_LT(total, grid::cell_count(kLevel) / 3);
}

TEST(NaturalEarth, UncutCountriesGiveTheCellsOfTheCutOnes) {
  const SiteSet uncut = read_layer("countries_110m");
  const SiteSet cut = read_layer("countries_110m_cut");
  ASSERT_EQ(uncut.geometry.site_count, cut.geometry.site_count);
  const auto fixed_uncut = test::fixed_cells_by_site(uncut.geometry);
  const auto fixed_cut = test::fixed_cells_by_site(cut.geometry);
  const auto sites_uncut = test::site_cells_by_site(uncut.geometry);
  const auto sites_cut = test::site_cells_by_site(cut.geometry);
  for (int s = 0; s < uncut.geometry.site_count; ++s) {
    ASSERT_EQ(name_of(uncut, s), name_of(cut, s));
    EXPECT_EQ(fixed_uncut[s], fixed_cut[s]) << name_of(uncut, s);
    // The cut adds edges along +-180 (and Natural Earth's Antarctica runs down it to the pole):
    // its extra site cells all touch that meridian.
    for (grid::Code c : sites_uncut[s]) EXPECT_TRUE(sites_cut[s].count(c)) << name_of(uncut, s) << " " << c;
    for (grid::Code c : sites_cut[s]) {
      if (sites_uncut[s].count(c)) continue;
      grid::LonLat v[3];
      grid::cell_vertices(grid::cell_of(c, kLevel), kLevel, v);
      const bool touches = std::any_of(v, v + 3, [](const grid::LonLat& p) { return std::abs(p.lon) == 180.0 || std::abs(p.lat) == 90.0; });
      EXPECT_TRUE(touches) << name_of(uncut, s) << " " << c;
    }
  }
  // Read flat (-wrap none), Russia's and Fiji's rings cover the world the other way round.
  const SiteSet flat = read_layer("countries_110m", WrapMode::none);
  std::size_t flat_total = 0, auto_total = 0;
  for (const auto& cells : test::fixed_cells_by_site(flat.geometry)) flat_total += cells.size();
  for (const auto& cells : fixed_uncut) auto_total += cells.size();
  EXPECT_NE(flat_total, auto_total);
}

}  // namespace
}  // namespace qtmv::sites

namespace qtmv::sites {
namespace {

// The readers build sites on all threads: the same pieces, site cells, fixed cells and nodes,
// table and summary with one thread as with several (the countries at level 8, and as lines).
/// A CSV with one large multipolygon (many rings, more vertices than one job takes) between two
/// small polygons: the large one is traced in shares by several threads.
std::string large_multipolygon_csv() {
  const std::string path = ::testing::TempDir() + "/large_multipolygon.csv";
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs("WKT,id\n\"POLYGON ((-30 -30,-20 -30,-20 -20,-30 -30))\",0\n\"MULTIPOLYGON (", f);
  for (int p = 0; p < 120; ++p) {
    const double lon = -170.0 + 340.0 * (p % 12) / 12.0, lat = -60.0 + 120.0 * (p / 12) / 10.0;
    std::fputs(p ? ",((" : "((", f);
    for (int k = 0; k <= 600; ++k) {
      const double a = 2 * M_PI * (k % 600) / 600.0, r = 4.0 + 1.5 * std::sin(7 * a + p);
      std::fprintf(f, "%s%.6f %.6f", k ? "," : "", lon + r * std::cos(a), lat + 0.5 * r * std::sin(a));
    }
    std::fputs("))", f);
  }
  std::fputs(")\",1\n\"POLYGON ((30 30,40 30,40 40,30 30))\",2\n", f);
  std::fclose(f);
  return path;
}

TEST(NaturalEarth, OneThreadAndSeveralReadTheSame) {
  for (const int source : {0, 1, 2}) {  // polygons, lines, a large multipolygon
    const bool as_lines = source == 1;
    SiteSet got[2];
    for (int k = 0; k < 2; ++k) {
      ReadOptions o = test::options_at(kLevel, nullptr);
      o.layers = {"countries_110m"};
      o.threads = k == 0 ? 1 : 4;
      if (as_lines) o.sql = "SELECT ST_Boundary(geom) AS geom, name FROM countries_110m";
      if (as_lines) o.layers.clear();
      if (source == 2) {
        o.layers.clear();
        got[k] = read_sites(large_multipolygon_csv(), o);
        EXPECT_EQ(got[k].geometry.site_count, 3);
        continue;
      }
      got[k] = read_sites(kCountries, o);
    }
    const SiteGeometry& a = got[0].geometry;
    const SiteGeometry& b = got[1].geometry;
    SCOPED_TRACE(source == 0 ? "polygons" : source == 1 ? "lines" : "large multipolygon");
    test::expect_same_geometry(a, b);
    EXPECT_EQ(as_lines, a.fixed_cells.empty() && a.fixed_nodes.empty());
    ASSERT_EQ(got[0].table.sites.size(), got[1].table.sites.size());
    for (std::size_t s = 0; s < got[0].table.sites.size(); ++s) {
      EXPECT_EQ(got[0].table.sites[s].fid, got[1].table.sites[s].fid);
      EXPECT_EQ(got[0].table.sites[s].fixed_cells, got[1].table.sites[s].fixed_cells);
    }
    EXPECT_EQ(got[0].summary.wrapped_features, got[1].summary.wrapped_features);
    EXPECT_EQ(got[0].summary.vertex_steps, got[1].summary.vertex_steps);
  }
}

}  // namespace
}  // namespace qtmv::sites
