// A batch's jobs built in slices by any thread's builder and appended in units taken in any
// order: the same arrays as its jobs built one by one by one builder (site ids the jobs' sites,
// piece indices moved past the pieces before), appended after what the read holds already.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "sites/append_sites.hpp"
#include "sites/site_batch.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

/// Features: points, lines, and polygons of several rings, one of them large enough to be
/// shared out in jobs.
FeatureParts make_features(std::vector<std::pair<std::size_t, std::size_t>>& ranges) {
  FeatureParts parts;
  std::mt19937_64 random(41);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto ring = [&](double lon, double lat, double r, int n, FeatureParts::Kind kind, int polygon) {
    const std::size_t begin = parts.points.size();
    for (int k = 0; k <= n; ++k) {
      const double a = 2.0 * M_PI * (k % n) / n;
      parts.points.push_back({lon + r * std::cos(a), lat + 0.5 * r * std::sin(a)});
    }
    parts.parts.push_back({kind, begin, parts.points.size(), polygon});
  };
  for (int f = 0; f < 3000; ++f) {
    const std::size_t first = parts.parts.size();
    const double lon = -170.0 + 340.0 * unit(random), lat = -70.0 + 140.0 * unit(random);
    if (f % 3 == 0) {
      parts.points.push_back({lon, lat});
      parts.parts.push_back({FeatureParts::kPoint, parts.points.size() - 1, parts.points.size(), -1});
    } else if (f % 3 == 1) {
      ring(lon, lat, 2.0, 7, FeatureParts::kLine, -1);
    } else {
      const int polygons = f == 8 ? 40 : 1;  // many polygons, shared out
      for (int p = 0; p < polygons; ++p) {
        ring(lon + 0.01 * p, lat, 1.0 + unit(random), f == 8 ? 300 : 12, FeatureParts::kRing, p);
        ring(lon + 0.01 * p, lat, 0.3, 5, FeatureParts::kRing, p);  // a hole
      }
    }
    ranges.emplace_back(first, parts.parts.size());
  }
  return parts;
}

TEST(AppendSites, SlicesAppendedInAnyOrderAreTheSitesBuiltOneByOne) {
  constexpr int kLevel = 9;
  std::vector<std::pair<std::size_t, std::size_t>> ranges;
  const FeatureParts parts = make_features(ranges);
  // What the read holds before the batch: 5 sites.
  SiteBuilder one(kLevel, EdgeShape::lonlat, WrapMode::automatic);
  const auto build = [&](std::size_t first, std::size_t last) {
    one.begin_site();
    for (std::size_t p = first; p < last;) {
      const FeatureParts::Part& part = parts.parts[p];
      if (part.kind == FeatureParts::kPoint) {
        one.add_point(parts.points[part.begin]);
        ++p;
      } else if (part.kind == FeatureParts::kLine) {
        one.add_line(parts.points.data() + part.begin, part.end - part.begin);
        ++p;
      } else {
        std::vector<LonLatPath> rings;
        for (const int polygon = part.polygon; p < last && parts.parts[p].polygon == polygon; ++p) {
          rings.emplace_back(parts.points.begin() + parts.parts[p].begin, parts.points.begin() + parts.parts[p].end);
        }
        one.add_polygon(rings);
      }
    }
    one.end_site();
  };
  for (std::size_t f = 0; f < 5; ++f) build(ranges[f].first, ranges[f].second);
  SiteGeometry got = one.geometry();

  ReadOptions options;
  options.level = kLevel;
  SiteBuilders builders(options, 4);
  SiteBatch batch;
  for (std::size_t f = 5; f < ranges.size(); ++f) {
    batch.add(static_cast<GIntBig>(f), static_cast<std::int32_t>(f), parts, ranges[f].first, ranges[f].second);
  }
  EXPECT_GT(batch.jobs().size(), ranges.size() - 5);  // the large feature is shared out
  batch.plan_slices();
  ASSERT_GT(batch.slice_count(), 8u);
  ReadTimes times;
  std::vector<std::size_t> order(batch.slice_count());
  for (std::size_t s = 0; s < order.size(); ++s) order[s] = s;
  std::reverse(order.begin(), order.end());
#pragma omp parallel for schedule(dynamic, 1) num_threads(4)
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(order.size()); ++k) {
    batch.build_slice(order[static_cast<std::size_t>(k)], builders, times);
  }
  SiteAppend append;
  append.plan(got, batch, 4);
  for (std::size_t u = append.unit_count(); u-- > 0;) append.copy(u);

  // The reference: the jobs built one by one by the one builder (its sites from 5 on are the
  // jobs), their sites then the jobs' sites.
  for (const SiteJob& job : batch.jobs()) {
    const auto first = static_cast<std::size_t>(job.parts - parts.parts.data());
    build(first, first + job.part_count);
  }
  SiteGeometry want = one.geometry();
  const auto site_of = [&](std::int32_t s) { return s < 5 ? s : batch.jobs()[static_cast<std::size_t>(s - 5)].site; };
  for (auto& p : want.pieces) p.site = site_of(p.site);
  for (auto& c : want.site_cells) c.site = site_of(c.site);
  for (auto& c : want.fixed_cells) c.site = site_of(c.site);
  for (auto& n : want.fixed_nodes) n.site = site_of(n.site);
  want.site_count = static_cast<std::int32_t>(ranges.size());
  test::expect_same_geometry(want, got);
}

}  // namespace
}  // namespace qtmv::sites
