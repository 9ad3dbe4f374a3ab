// Regions' geodesic areas summed edge by edge from the outline cells (region_measures), checked
// against GeographicLib's PolygonArea of every cell, added up per site.
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/PolygonArea.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "geodesic_reference.hpp"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"
#include "write/region_measures.hpp"

namespace qtmv::write {
namespace {

using grid::Code;

using test::kEllipsoidArea;

using test::cell_area;

/// Labels of a level for `sites` random sites, nearest by a rough lon/lat distance, and on top
/// of them shapes that test the reduction: a cap around the north pole (one site), a band
/// across +-180, and a ring (a region with a hole holding another site).
std::vector<std::int32_t> scene(int level, std::int32_t sites, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-90, 90);
  std::vector<LonLat> at(static_cast<std::size_t>(sites));
  for (auto& p : at) p = {lon(rng), lat(rng)};
  std::vector<std::int32_t> labels(grid::cell_count(level));
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    const LonLat c = grid::cell_centre(code, level);
    std::int32_t best = 0;
    double best_d = 1e300;
    for (std::int32_t s = 0; s < sites; ++s) {
      const double dx = std::remainder(c.lon - at[s].lon, 360.0) * std::cos(c.lat * grid::kDegree), dy = c.lat - at[s].lat;
      if (dx * dx + dy * dy < best_d) best_d = dx * dx + dy * dy, best = s;
    }
    if (sites >= 4) {
      if (c.lat > 70) best = 0;
      if (std::fabs(c.lon) > 170 && std::fabs(c.lat) < 20) best = 1;
      const double r = std::hypot(c.lon - 40, c.lat + 30);
      if (r < 15 && r > 7) best = 2;
      if (r <= 4) best = 3;
    }
    labels[code] = best;
  }
  return labels;
}

void expect_areas_of_cells(int level, std::int32_t sites, unsigned seed) {
  const std::vector<std::int32_t> labels = scene(level, sites, seed);
  std::vector<double> expected(static_cast<std::size_t>(sites), 0.0);
  for (Code code = 0; code < grid::cell_count(level); ++code) expected[labels[code]] += cell_area(code, level);
  const std::vector<double> got = region_areas(label::outlines_of_dense(level, labels.data(), nullptr, sites));
  ASSERT_EQ(got.size(), expected.size());
  double total = 0;
  for (std::size_t s = 0; s < got.size(); ++s) {
    // Sums of the same geodesics' areas in another order: round-off, and kAreaUnit an edge.
    EXPECT_NEAR(got[s], expected[s], 1e-12 * kEllipsoidArea) << "level " << level << ", site " << s;
    total += got[s];
  }
  EXPECT_NEAR(total, kEllipsoidArea, 1e-12 * kEllipsoidArea);
}

TEST(RegionMeasures, AreasEqualTheirCellsAreas) {
  for (int level = 1; level <= 6; ++level) {
    for (const std::int32_t sites : {1, 2, 5, 40}) expect_areas_of_cells(level, sites, 7u * level + sites);
  }
}

TEST(RegionMeasures, OneSiteIsTheWholeEllipsoid) {
  for (int level = 0; level <= 4; ++level) {
    const std::vector<std::int32_t> labels(grid::cell_count(level), 0);
    const std::vector<double> got = region_areas(label::outlines_of_dense(level, labels.data(), nullptr, 1));
    EXPECT_NEAR(got[0], kEllipsoidArea, 1e-12 * kEllipsoidArea) << "level " << level;
  }
}

TEST(RegionMeasures, SitesWithoutCellsHaveNoArea) {
  const int level = 4;
  std::vector<std::int32_t> labels = scene(level, 6, 3);
  for (auto& s : labels) s = s == 5 ? 4 : s;  // site 5 loses its cells
  const std::vector<double> got = region_areas(label::outlines_of_dense(level, labels.data(), nullptr, 6));
  EXPECT_EQ(got[5], 0.0);
  EXPECT_GT(got[4], 0.0);
}

TEST(RegionMeasures, SameBitsWhateverTheThreads) {
#ifdef _OPENMP
  const int level = 7;
  const std::vector<std::int32_t> labels = scene(level, 300, 11);
  const label::Outlines outlines = label::outlines_of_dense(level, labels.data(), nullptr, 300);
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const std::vector<double> one = region_areas(outlines);
  omp_set_num_threads(4);
  const std::vector<double> four = region_areas(outlines);
  omp_set_num_threads(before);
  ASSERT_EQ(one.size(), four.size());
  for (std::size_t s = 0; s < one.size(); ++s) EXPECT_EQ(one[s], four[s]) << "site " << s;
#else
  GTEST_SKIP() << "built without OpenMP";
#endif
}

TEST(RegionMeasures, ManySitesInNoSpatialOrder) {
  // Tens of thousands of small regions whose ids are shuffled, as a million random points' are:
  // a thread's slots for the sites' sums are taken by other sites all the time and handed to the
  // shared sums many at a time. The areas still equal their cells', on any number of threads, to
  // the same bits.
  const int level = 8;
  std::vector<Code> ancestor(grid::cell_count(level));
  for (Code code = 0; code < grid::cell_count(level); ++code) ancestor[code] = grid::parent(grid::parent(code, level), level - 1);
  const auto sites = static_cast<std::int32_t>(grid::cell_count(level - 2));
  std::vector<std::int32_t> id(static_cast<std::size_t>(sites));
  for (std::int32_t s = 0; s < sites; ++s) id[static_cast<std::size_t>(s)] = s;
  std::shuffle(id.begin(), id.end(), std::mt19937(5));
  std::vector<std::int32_t> labels(grid::cell_count(level));
  std::vector<double> expected(static_cast<std::size_t>(sites), 0.0);
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    labels[code] = id[ancestor[code]];
    expected[static_cast<std::size_t>(labels[code])] += cell_area(code, level);
  }
  const label::Outlines outlines = label::outlines_of_dense(level, labels.data(), nullptr, sites);
  std::vector<double> first;
  for (int threads : {1, 2, 4}) {
#ifdef _OPENMP
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
#endif
    RegionAreaSums sums(sites);
    const RegionTracer tracer(outlines, RingVertices::corners, {}, &sums);
    const std::vector<double> got = sums.areas(outlines.cells_per_site);
#ifdef _OPENMP
    omp_set_num_threads(before);
#endif
    ASSERT_EQ(got.size(), expected.size());
    if (first.empty()) first = got;
    for (std::size_t s = 0; s < got.size(); ++s) {
      ASSERT_NEAR(got[s], expected[s], 1e-12 * kEllipsoidArea) << threads << " threads, site " << s;
      ASSERT_EQ(got[s], first[s]) << threads << " threads, site " << s;
    }
  }
}

TEST(RegionMeasures, TracerPassGivesTheSameAreasWhateverTheThreads) {
  // The writer's way: the sums taken in RegionTracer's gathering pass, on 1 and 4 threads, equal
  // region_areas' own pass to the bit; and the regions traced are the same with and without it.
  const int level = 7;
  const std::vector<std::int32_t> labels = scene(level, 300, 13);
  const label::Outlines outlines = label::outlines_of_dense(level, labels.data(), nullptr, 300);
  const std::vector<double> expected = region_areas(outlines);
  const RegionTracer plain(outlines);
  for (int threads : {1, 4}) {
#ifdef _OPENMP
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
#endif
    RegionAreaSums sums(outlines.site_count);
    const RegionTracer tracer(outlines, RingVertices::corners, {}, &sums);
    const std::vector<double> got = sums.areas(outlines.cells_per_site);
#ifdef _OPENMP
    omp_set_num_threads(before);
#endif
    ASSERT_EQ(got.size(), expected.size());
    for (std::size_t s = 0; s < got.size(); ++s) {
      ASSERT_EQ(got[s], expected[s]) << threads << " threads, site " << s;
      const Region a = tracer.trace(static_cast<std::int32_t>(s)), b = plain.trace(static_cast<std::int32_t>(s));
      ASSERT_EQ(a.size(), b.size()) << "site " << s;
      for (std::size_t p = 0; p < a.size(); ++p) {
        ASSERT_EQ(a[p].shell.size(), b[p].shell.size());
        for (std::size_t k = 0; k < a[p].shell.size(); ++k) {
          ASSERT_TRUE(same_point(a[p].shell[k], b[p].shell[k])) << "site " << s;
        }
        ASSERT_EQ(a[p].holes.size(), b[p].holes.size());
      }
    }
  }
}

}  // namespace
}  // namespace qtmv::write
