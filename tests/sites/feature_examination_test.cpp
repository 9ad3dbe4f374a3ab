// The features of a chunk examined in blocks on any thread: their parts in the block's arrays
// and their skips.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include <ogr_spatialref.h>

#include "sites/feature_examination.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::srs_of;

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
