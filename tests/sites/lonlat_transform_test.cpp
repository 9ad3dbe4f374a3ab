// Coordinates to lon/lat: to_lonlat (a failure leaves the points as given, a latitude rounded
// beyond +-90 is set to +-90) and each thread's own copy of the layer's transformation, which
// gives the layer's bits.
#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <string>
#include <vector>

#include <ogr_spatialref.h>

#include "common/openmp_threads.hpp"
#include "sites/lonlat_transform.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::srs_of;

TEST(LonLatTransform, ToLonLatChecksLatitudesAndLeavesAFailureAsGiven) {
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

TEST(LonLatTransform, EachThreadHasItsOwnCopyOfTheTransformation) {
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

}  // namespace
}  // namespace qtmv::sites
