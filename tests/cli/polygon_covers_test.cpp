// Polygon interiors as covers, end to end through the reader and the labeller: the labels,
// distances and boundary flags of the reader's cover (fixed nodes and ring cells) equal those of
// the same claims enumerated cell by cell, on Natural Earth and on the bad-input catalogue's odd
// polygons, on the CPU and (where there is one) the GPU.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "label/fixed_cover.hpp"
#include "label/labeller.hpp"
#include "sites/ogr_site_reader.hpp"

namespace qtmv {
namespace {

/// A CSV of WKT polygons (and points), one site each.
std::string wkt_csv(const std::string& name, const std::vector<std::string>& wkts) {
  const std::string path = ::testing::TempDir() + "/" + name + ".csv";
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs("WKT,id\n", f);
  for (std::size_t k = 0; k < wkts.size(); ++k) std::fprintf(f, "\"%s\",%zu\n", wkts[k].c_str(), k);
  std::fclose(f);
  return path;
}

void expect_cover_labels_as_cells(const std::string& source, const std::string& layer, int level) {
  sites::ReadOptions read;
  read.level = level;
  if (!layer.empty()) read.layers = {layer};
  const sites::SiteSet set = sites::read_sites(source, read);
  const label::LabelInput with_nodes = set.geometry.input();
  ASSERT_GT(with_nodes.fixed_node_count, 0u) << source;
  label::SiteGeometry cells = set.geometry;
  const std::vector<label::FixedCell> all = label::fixed_cells_with_nodes(with_nodes);
  cells.fixed_cells.assign(all.begin(), all.end());
  cells.fixed_nodes.clear();
  std::vector<std::string> devices{"cpu"};
  if (label::cuda_device_count() > 0) devices.push_back("cuda");
  for (const std::string& device : devices) {
    for (const label::Rule rule : {label::Rule::exact, label::Rule::cell}) {
      SCOPED_TRACE(source + " level " + std::to_string(level) + " " + device +
                   (rule == label::Rule::exact ? " exact" : " cell"));
      label::LabelOptions options;
      options.device = device;
      options.rule = rule;
      options.algorithm = label::Algorithm::hier;
      const label::LabelResult a = label::label_all(with_nodes, options);
      const label::LabelResult b = label::label_all(cells.input(), options);
      std::size_t sites = 0, metres = 0, flags = 0;
      for (std::size_t c = 0; c < a.site.size(); ++c) {
        if (a.site[c] != b.site[c] && sites < 5) {
          ADD_FAILURE() << "cell " << c << ": " << a.site[c] << " against " << b.site[c] << " at " << a.distance_m[c]
                        << " m";
        }
        sites += a.site[c] != b.site[c];
        metres += a.distance_m[c] != b.distance_m[c];
        flags += a.boundary[c] != b.boundary[c];
      }
      EXPECT_EQ(sites, 0u);
      EXPECT_EQ(metres, 0u);
      EXPECT_EQ(flags, 0u);
    }
  }
}

TEST(PolygonCovers, NaturalEarthLabelsAsItsCells) {
  const std::string countries = std::string(QTMV_TESTDATA_DIR) + "/world_atlas_countries_110m.gpkg";
  for (const int level : {6, 8}) expect_cover_labels_as_cells(countries, "countries_110m", level);
}

TEST(PolygonCovers, OddPolygonsLabelAsTheirCells) {
  // The catalogue's odd polygons: a bow tie, a band round the globe, a cap round a pole, holes,
  // overlapping polygons; and points between them.
  const std::string source = wkt_csv(
      "odd_polygons", {"POLYGON ((20 0,30 10,30 0,20 10,20 0))",
                       "POLYGON ((-170 -80,-85 -80,0 -80,85 -80,170 -80,170 80,85 80,0 80,-85 80,-170 80,-170 -80))",
                       "POLYGON ((0 60,90 60,180 60,-90 60,0 60))",
                       "POLYGON ((-60 -50,-20 -50,-20 -10,-60 -10,-60 -50),(-50 -40,-30 -40,-30 -20,-50 -20,-50 -40))",
                       "POLYGON ((-45 -45,-35 -45,-35 -5,-45 -5,-45 -45))", "POINT (100 -85)", "POINT (-120 20)"});
  for (const int level : {5, 7}) expect_cover_labels_as_cells(source, "odd_polygons", level);
}

}  // namespace
}  // namespace qtmv
