// The features of a chunk examined in blocks on any thread: their parts in the block's arrays,
// their skips, and their coordinates in lon/lat through each thread's copy of the layer's
// transformation (to_lonlat: a failure leaves the points as given, a latitude rounded beyond
// +-90 is set to +-90).
#include <gtest/gtest.h>

#include <cstring>
#include <set>
#include <vector>

#include <ogr_spatialref.h>

#include "common/openmp_threads.hpp"
#include "sites/feature_examination.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

OGRSpatialReference srs_of(const char* text) {
  OGRSpatialReference srs;
  srs.SetFromUserInput(text);
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

TEST(FeatureExamination, ToLonLatChecksLatitudesAndLeavesAFailureAsGiven) {
  gdal::ErrorCapture errors;
  LonLatScratch scratch;
  std::string reason;
  std::vector<grid::LonLat> points = {{10, 90 + 1e-10}, {20, -45}};
  EXPECT_EQ(to_lonlat(points.data(), points.size(), nullptr, errors, scratch, reason), Skip::none);
  EXPECT_EQ(points[0].lat, 90.0);
  points = {{10, 90.5}};
  EXPECT_EQ(to_lonlat(points.data(), points.size(), nullptr, errors, scratch, reason), Skip::coordinate);
  EXPECT_EQ(reason, "latitude beyond +-90 at (10, 90.5)");

  const OGRSpatialReference wgs84 = srs_of("EPSG:4326"), mercator = srs_of("EPSG:3857"),
                             ortho = srs_of("+proj=ortho +lat_0=0 +lon_0=0 +datum=WGS84");
  std::unique_ptr<OGRCoordinateTransformation> from_mercator(OGRCreateCoordinateTransformation(&mercator, &wgs84));
  points = {{1113194.9079327357, 0}, {0, 1118889.9748579594}};
  EXPECT_EQ(to_lonlat(points.data(), points.size(), from_mercator.get(), errors, scratch, reason), Skip::none);
  EXPECT_NEAR(points[0].lon, 10.0, 1e-9);
  EXPECT_NEAR(points[1].lat, 10.0, 1e-9);
  std::unique_ptr<OGRCoordinateTransformation> from_ortho(OGRCreateCoordinateTransformation(&ortho, &wgs84));
  points = {{0, 0}, {7e6, 0}};  // the second outside the orthographic disc
  EXPECT_EQ(to_lonlat(points.data(), points.size(), from_ortho.get(), errors, scratch, reason), Skip::transform);
  EXPECT_EQ(points[1].lon, 7e6);  // as given
  EXPECT_EQ(reason.rfind("coordinate (7000000, 0) fails to transform to WGS84", 0), 0u) << reason;
}

TEST(FeatureExamination, EachThreadHasItsOwnCopyOfTheTransformation) {
  const OGRSpatialReference wgs84 = srs_of("EPSG:4326"), utm = srs_of("EPSG:32633");
  std::unique_ptr<OGRCoordinateTransformation> layer(OGRCreateCoordinateTransformation(&utm, &wgs84));
  ThreadTransforms transforms(layer.get(), 4);
  ASSERT_TRUE(transforms.any());
  std::vector<OGRCoordinateTransformation*> copies(4, nullptr);
  std::vector<std::vector<grid::LonLat>> got(4);
#pragma omp parallel num_threads(4)
  {
    const auto k = static_cast<std::size_t>(thread_index());
    copies[k] = transforms.of_this_thread();
    gdal::ErrorCapture errors;
    LonLatScratch scratch;
    std::string reason;
    got[k] = {{500000, 5000000}, {400000, 6000000}};
    to_lonlat(got[k].data(), got[k].size(), copies[k], errors, scratch, reason);
  }
  double x[2] = {500000, 400000}, y[2] = {5000000, 6000000};
  layer->Transform(2, x, y);
  EXPECT_EQ(std::set<OGRCoordinateTransformation*>(copies.begin(), copies.end()).size(), copies.size());
  for (std::size_t k = 0; k < copies.size(); ++k) {
    ASSERT_NE(copies[k], nullptr);
    EXPECT_NE(copies[k], layer.get());
    EXPECT_EQ(got[k][0].lon, x[0]);  // bit for bit the layer's
    EXPECT_EQ(got[k][1].lat, y[1]);
  }
  EXPECT_FALSE(ThreadTransforms(nullptr, 4).any());
}

TEST(FeatureExamination, BlocksHoldTheirFeaturesPartsAndSkips) {
  const OGRSpatialReference wgs84 = srs_of("EPSG:4326");
  const CoordinateRange range = coordinate_range(wgs84);
  ReadOptions options;
  const PolygonValidityCheck validity(options, wgs84, "'test'");
  ThreadTransforms transforms(nullptr, 1);
  const Examination examination{range, validity, transforms};
  OGRFeatureDefn* definition = new OGRFeatureDefn("f");
  definition->Reference();
  FeatureChunk chunk;
  gdal::ErrorCapture errors;
  const std::vector<std::string> wkts = {"POINT (1 2)", "POLYGON EMPTY", "LINESTRING (0 0,1 1,2 0)",
                                         "POINT (600 0)", "CIRCULARSTRING (0 0,1 1,2 0)",
                                         "POLYGON ((0 0,4 0,4 4,0 0),(1 0.5,2 0.5,2 1,1 0.5))", ""};
  for (int copy = 0; copy < 400; ++copy) {  // 2800 features: several blocks
    for (const std::string& wkt : wkts) {
      OGRFeatureUniquePtr feature(OGRFeature::CreateFeature(definition));
      feature->SetFID(static_cast<GIntBig>(chunk.size()));
      if (!wkt.empty()) feature->SetGeometryDirectly(test::from_wkt(wkt).release());
      chunk.add(std::move(feature), errors);
    }
  }
  ASSERT_GT(chunk.block_count(), 2u);
  for (std::size_t b = chunk.block_count(); b-- > 0;) chunk.examine_block(b, examination);
  for (std::size_t k = 0; k < chunk.size(); ++k) {
    const PendingFeature& f = chunk.feature(k);
    const FeatureParts& parts = chunk.block_parts(f.block);
    const std::size_t n = f.part_end - f.part_begin;
    switch (k % wkts.size()) {
      case 0:
        ASSERT_EQ(n, 1u);
        EXPECT_EQ(parts.points[parts.parts[f.part_begin].begin].lat, 2.0);
        break;
      case 1:
      case 6:
        EXPECT_EQ(f.skip, Skip::empty);
        EXPECT_EQ(f.skip_reason, "empty geometry");
        break;
      case 3:
        EXPECT_EQ(f.skip, Skip::coordinate);
        EXPECT_EQ(f.skip_reason, "coordinate (600, 0) beyond +-540 degrees of its CRS");
        EXPECT_EQ(n, 0u);
        break;
      case 4:
        ASSERT_EQ(n, 1u);  // linearised
        EXPECT_GT(parts.parts[f.part_begin].end - parts.parts[f.part_begin].begin, 3u);
        break;
      case 5:
        ASSERT_EQ(n, 2u);  // shell and hole of polygon 0
        EXPECT_EQ(parts.parts[f.part_begin + 1].polygon, 0);
        EXPECT_EQ(parts.parts[f.part_begin + 1].kind, FeatureParts::kRing);
        break;
      default:
        EXPECT_EQ(n, 1u);
    }
    if (k % wkts.size() != 1 && k % wkts.size() != 3 && k % wkts.size() != 6) {
      EXPECT_EQ(f.skip, Skip::none) << k;
    }
  }
  chunk.clear();
  EXPECT_EQ(chunk.size(), 0u);
  EXPECT_EQ(chunk.block_count(), 0u);
  definition->Release();
}

}  // namespace
}  // namespace qtmv::sites
