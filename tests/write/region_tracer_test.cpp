// Regions traced from the grid's topology, checked with GEOS (through OGR): valid polygons,
// and each region covers exactly its cells.
#include <gtest/gtest.h>

#include <ogr_api.h>
#include <ogr_geometry.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#if defined(_OPENMP)
#include <omp.h>
#endif

#include "common/openmp_threads.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_code_ranges.hpp"
#include "write/region_measures.hpp"
#include "write/region_tracer.hpp"

namespace qtmv::write {
namespace {

using grid::Code;

constexpr double kGlobeSquareDegrees = 360.0 * 180.0;

std::unique_ptr<OGRMultiPolygon> to_ogr(const Region& region) {
  auto multi = std::make_unique<OGRMultiPolygon>();
  for (const RegionPolygon& part : region) {
    OGRPolygon polygon;
    auto add_ring = [&](const std::vector<LonLat>& ring) {
      OGRLinearRing r;
      for (const LonLat& p : ring) r.addPoint(p.lon, p.lat);
      r.closeRings();
      polygon.addRing(&r);
    };
    add_ring(part.shell);
    for (const auto& hole : part.holes) add_ring(hole);
    multi->addGeometry(&polygon);
  }
  return multi;
}

/// Area of the cell as drawn in lon/lat (square degrees).
double drawn_cell_area(Code code, int level) {
  LonLat ring[grid::kMaxPolygonCorners];
  const int n = grid::cell_polygon(grid::cell_of(code, level), level, ring);
  return planar_ring_area(std::vector<LonLat>(ring, ring + n));
}

/// Checks every region: valid by GEOS, its area equal to its cells' area, all areas adding up
/// to the whole lon/lat rectangle, and a sample of cell centres inside their own region.
void check_regions(int level, const std::vector<std::int32_t>& labels, std::int32_t sites) {
  const std::vector<Region> regions = trace_regions(level, labels.data(), sites);
  ASSERT_EQ(regions.size(), static_cast<std::size_t>(sites));
  std::vector<double> cell_area(static_cast<std::size_t>(sites), 0.0);
  for (Code code = 0; code < grid::cell_count(level); ++code) cell_area[labels[code]] += drawn_cell_area(code, level);

  std::vector<std::unique_ptr<OGRMultiPolygon>> shapes;
  double total = 0;
  for (std::int32_t s = 0; s < sites; ++s) {
    shapes.push_back(to_ogr(regions[s]));
    EXPECT_TRUE(shapes.back()->IsValid()) << "site " << s << ": " << shapes.back()->exportToWkt();
    const double area = shapes.back()->get_Area();
    EXPECT_NEAR(area, cell_area[s], 1e-9 * kGlobeSquareDegrees) << "site " << s;
    for (const RegionPolygon& part : regions[s]) {
      for (const LonLat& p : part.shell) {
        EXPECT_LE(std::fabs(p.lon), 180.0);
        EXPECT_LE(std::fabs(p.lat), 90.0);
      }
    }
    total += area;
  }
  EXPECT_NEAR(total, kGlobeSquareDegrees, 1e-9 * kGlobeSquareDegrees);

  std::mt19937_64 rng(11);
  std::uniform_int_distribution<Code> pick(0, grid::cell_count(level) - 1);
  for (int k = 0; k < 300; ++k) {
    const Code code = pick(rng);
    const LonLat c = grid::cell_centre(code, level);
    OGRPoint point(c.lon, c.lat);
    EXPECT_TRUE(shapes[labels[code]]->Contains(&point)) << "cell " << code << " of site " << labels[code];
  }
}

std::vector<std::int32_t> nearest_point_labels(int level, int sites, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-1, 1);
  std::vector<grid::Vec3> points;
  for (int s = 0; s < sites; ++s) points.push_back(grid::unit_vector(lon(rng), std::asin(z(rng)) / grid::kDegree));
  std::vector<std::int32_t> labels(grid::cell_count(level));
  for (Code code = 0; code < labels.size(); ++code) {
    const grid::Vec3 x = grid::cell_centre_vector(code, level);
    int best = 0;
    for (int s = 1; s < sites; ++s)
      if (grid::chord2(x, points[s]) < grid::chord2(x, points[best])) best = s;
    labels[code] = best;
  }
  return labels;
}

/// The outlines of one range of whole rows, as a tile job's labeller gives them: the level's
/// outline cells in the range, and the range's cells per site.
label::Outlines tile_outlines(const label::Outlines& whole, grid::CodeRange range) {
  label::Outlines tile;
  tile.level = whole.level;
  tile.site_count = whole.site_count;
  tile.range = range;
  for (const label::OutlineCell& c : whole.cells) {
    if (c.code() >= range.first && c.code() < range.end) tile.cells.push_back(c);
  }
  tile.cells_per_site = label::count_cells_per_site(tile.cells, whole.level, whole.site_count, range.end);
  return tile;
}

/// Splits the level in `tiles` ranges and traces each range's regions, cut at its edges: each
/// piece valid and covering exactly its site's cells of the range (GEOS), the pieces of a site
/// uniting into its whole region, and the pieces' areas (region_areas) adding up to its area.
void check_tiles(int level, const std::vector<std::int32_t>& labels, std::int32_t sites, int tiles) {
  SCOPED_TRACE(std::to_string(tiles) + " tiles");
  const label::Outlines whole = label::outlines_of_dense(level, labels.data(), nullptr, sites);
  const std::vector<Region> regions = trace_regions(whole);
  const std::vector<double> areas = region_areas(whole);
  std::vector<OGRMultiPolygon> pieces(static_cast<std::size_t>(sites));
  std::vector<double> area_sums(static_cast<std::size_t>(sites), 0.0);
  int cut = 0;
  for (const grid::CodeRange& range : grid::split_in_rows(grid::whole_level(level), tiles, level)) {
    const label::Outlines tile = tile_outlines(whole, range);
    label::check_outlines(tile);
    const std::vector<Region> parts = trace_regions(tile);
    const std::vector<double> part_areas = region_areas(tile);
    std::vector<double> cell_area(static_cast<std::size_t>(sites), 0.0);
    for (Code code = range.first; code < range.end; ++code) cell_area[labels[code]] += drawn_cell_area(code, level);
    for (std::int32_t s = 0; s < sites; ++s) {
      const std::unique_ptr<OGRMultiPolygon> shape = to_ogr(parts[s]);
      EXPECT_EQ(parts[s].empty(), tile.cells_per_site[s] == 0) << "site " << s;
      EXPECT_TRUE(shape->IsValid()) << "site " << s << ": " << shape->exportToWkt();
      EXPECT_NEAR(shape->get_Area(), cell_area[s], 1e-9 * kGlobeSquareDegrees) << "site " << s;
      for (const OGRPolygon* p : *shape) pieces[s].addGeometry(p);
      area_sums[s] += part_areas[s];
      cut += parts[s].empty() || tile.cells_per_site[s] == whole.cells_per_site[s] ? 0 : 1;
    }
  }
  EXPECT_GT(cut, 0);
  for (std::int32_t s = 0; s < sites; ++s) {
    const std::unique_ptr<OGRGeometry> joined(pieces[s].UnionCascaded());
    ASSERT_TRUE(joined) << "site " << s;
    const std::unique_ptr<OGRMultiPolygon> region = to_ogr(regions[s]);
    const std::unique_ptr<OGRGeometry> difference(joined->SymDifference(region.get()));
    ASSERT_TRUE(difference);
    EXPECT_LT(difference->IsEmpty() ? 0.0 : OGR_G_Area(OGRGeometry::ToHandle(difference.get())), 1e-9) << "site " << s;
    EXPECT_NEAR(area_sums[s], areas[s], 1e-9 * areas[s]) << "site " << s;
  }
}

TEST(RegionTracer, TilesCutRegionsAtTheirEdges) {
  for (int level : {3, 5}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const std::vector<std::int32_t> nearest = nearest_point_labels(level, 25, 7);
    for (int tiles : {2, 5, 16}) check_tiles(level, nearest, 25, tiles);
  }
  // Random labels: pieces that touch themselves at vertices along the tiles' edges too.
  std::mt19937_64 rng(4);
  std::uniform_int_distribution<std::int32_t> site(0, 2);
  std::vector<std::int32_t> labels(grid::cell_count(4));
  for (auto& l : labels) l = site(rng);
  check_tiles(4, labels, 3, 7);
}

/// Whether two regions are the same rings, vertex for vertex, in the same order.
bool same_region(const Region& a, const Region& b) {
  const auto same_ring = [](const std::vector<LonLat>& p, const std::vector<LonLat>& q) {
    if (p.size() != q.size()) return false;
    for (std::size_t k = 0; k < p.size(); ++k) {
      if (!same_point(p[k], q[k])) return false;
    }
    return true;
  };
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (!same_ring(a[k].shell, b[k].shell) || a[k].holes.size() != b[k].holes.size()) return false;
    for (std::size_t h = 0; h < a[k].holes.size(); ++h) {
      if (!same_ring(a[k].holes[h], b[k].holes[h])) return false;
    }
  }
  return true;
}

TEST(RegionTracer, RangeEdgesFlagEveryCellWithANeighbourOutsideWhateverTheThreads) {
  // Every cell of a tile with a neighbour outside it becomes an outline cell flagged as a boundary
  // cell (its site the cell's), and the others stay as they were: checked cell by cell against
  // every code of the range, for tiles of several levels, at 1 to 8 threads.
  for (const auto& [level, sites] : {std::pair{3, 9}, {5, 30}, {6, 4}}) {
    const std::vector<std::int32_t> labels = nearest_point_labels(level, sites, 11);
    const label::Outlines whole = label::outlines_of_dense(level, labels.data(), nullptr, sites);
    for (const int tiles : {2, 3, 8, 16}) {
      for (const grid::CodeRange& range : grid::split_in_rows(grid::whole_level(level), tiles, level)) {
        SCOPED_TRACE("level " + std::to_string(level) + ", tile [" + std::to_string(range.first) + ", " +
                     std::to_string(range.end) + ")");
        const label::Outlines tile = tile_outlines(whole, range);
        // The reference: each code of the range, in order.
        std::vector<label::OutlineCell> want;
        std::size_t k = 0;
        for (Code code = range.first; code < range.end; ++code) {
          Code nb[3];
          grid::neighbours(code, level, nb);
          const bool outside = !holds_code(tile, nb[0]) || !holds_code(tile, nb[1]) || !holds_code(tile, nb[2]);
          const bool listed = k < tile.cells.size() && tile.cells[k].code() == code;
          if (listed) {
            want.push_back(tile.cells[k++]);
            if (outside) want.back().mark_boundary();
          } else if (outside) {
            want.push_back(label::OutlineCell(code, labels[code], 1));
          }
        }
        for (const int threads : {1, 2, 3, 8}) {
          const ScopedDefaultThreads use(threads);
          const label::Outlines got = with_range_edges(tile);
          ASSERT_EQ(got.cells.size(), want.size()) << threads << " threads";
          std::size_t wrong = 0;
          for (std::size_t c = 0; c < want.size(); ++c) {
            wrong += got.cells[c].code() != want[c].code() || got.cells[c].site != want[c].site ||
                     got.cells[c].boundary() != want[c].boundary();
          }
          EXPECT_EQ(wrong, 0u) << threads << " threads";
          EXPECT_EQ(got.cells_per_site, tile.cells_per_site);
          EXPECT_EQ(got.range.first, range.first);
        }
      }
    }
  }
}

TEST(RegionTracer, RegionEdgesAreEveryDrawnEdgeToAnotherSiteOrOnTheBorder) {
  // visit_region_edges draws a cell's corners only when asked and looks for border edges on row
  // ends only: checked against every drawn edge of every cell of levels 0 to 6 (whole levels, and
  // tiles cut at their edges), each edge's site across it from the dense labels, its corners from
  // drawn_ring.
  struct Seen {
    Code code;
    int edge;
    std::int32_t other;
    LonLat from, to;
    bool operator==(const Seen& o) const {
      return code == o.code && edge == o.edge && other == o.other && same_point(from, o.from) && same_point(to, o.to);
    }
  };
  std::mt19937_64 rng(31);
  for (int level = 0; level <= 6; ++level) {
    std::vector<std::int32_t> scattered(grid::cell_count(level));
    std::uniform_int_distribution<std::int32_t> site(0, 2);
    for (auto& l : scattered) l = site(rng);
    for (const auto& [sites, labels] : {std::make_pair(3, scattered), std::make_pair(12, nearest_point_labels(level, 12, 7))}) {
      const label::Outlines whole = label::outlines_of_dense(level, labels.data(), nullptr, sites);
      for (const int tiles : {1, 3}) {
        for (const grid::CodeRange& range : grid::split_in_rows(grid::whole_level(level), tiles, level)) {
          SCOPED_TRACE("level " + std::to_string(level) + ", " + std::to_string(sites) + " sites, tile [" +
                       std::to_string(range.first) + ", " + std::to_string(range.end) + ")");
          const label::Outlines tile = with_range_edges(tiles == 1 ? whole : tile_outlines(whole, range));
          std::vector<Seen> want, got;
          for (Code code = range.first; code < range.end; ++code) {
            const grid::Cell cell = grid::cell_of(code, level);
            LonLat ring[grid::kMaxPolygonCorners];
            int across[grid::kMaxPolygonCorners];
            const int corners = drawn_ring(cell, level, ring, across);
            Code nb[3];
            grid::neighbours(code, level, nb);
            for (int e = 0; e < corners; ++e) {
              const LonLat& from = ring[e];
              const LonLat& to = ring[(e + 1) % corners];
              std::int32_t other = kBorderEdge;
              if (across[e] != kAcrossPoleLine && !on_cut(from, to) && holds_code(tile, nb[across[e]])) {
                other = labels[nb[across[e]]];
                if (other == labels[code]) continue;
              }
              want.push_back({code, e, other, from, to});
            }
          }
          OutlineWalk walk;
          for (std::size_t k = 0; k < tile.cells.size(); ++k) {
            visit_region_edges(tile, k, walk, [&](int e, std::int32_t other, DrawnCorners& corners) {
              got.push_back({tile.cells[k].code(), e, other, corners.from(e), corners.to(e)});
            });
          }
          ASSERT_EQ(got.size(), want.size());
          EXPECT_TRUE(got == want);
        }
      }
    }
  }
}

TEST(RegionTracer, SameRegionsWhateverTheThreads) {
#if defined(_OPENMP)
  // The bucketing's threads each take a stretch of the outline cells and pack their part of a
  // site's list on their own (its first cell whole): a site's list then has parts from several
  // threads, which must read back as the one list of one thread.
  const int level = 6;
  std::mt19937_64 rng(23);
  std::uniform_int_distribution<std::int32_t> site(0, 3);
  std::vector<std::int32_t> labels(grid::cell_count(level));
  for (auto& l : labels) l = site(rng);  // every site's cells all over the level
  for (const auto& [sites, cells] : {std::make_pair(40, nearest_point_labels(level, 40, 3)), std::make_pair(4, labels)}) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const std::vector<Region> one = trace_regions(level, cells.data(), sites);
    for (int threads : {2, 3, 8}) {
      omp_set_num_threads(threads);
      const std::vector<Region> many = trace_regions(level, cells.data(), sites);
      ASSERT_EQ(many.size(), one.size());
      for (std::size_t s = 0; s < one.size(); ++s) EXPECT_TRUE(same_region(many[s], one[s])) << threads << " threads, site " << s;
    }
    omp_set_num_threads(before);
  }
#else
  GTEST_SKIP() << "no OpenMP";
#endif
}

TEST(RegionTracer, OutlineWalkGivesEveryCodesCell) {
  // The walk finds a row once for the codes of the row that follow: every code in order, codes
  // that skip rows and octants, and codes that go back.
  for (int level : {0, 1, 4, 7}) {
    OutlineWalk walk;
    const auto check = [&](Code code) {
      const grid::Cell want = grid::cell_of(code, level), got = walk.cell(code, level);
      ASSERT_EQ(got.octant, want.octant) << "level " << level << ", code " << code;
      ASSERT_EQ(got.row, want.row) << "level " << level << ", code " << code;
      ASSERT_EQ(got.col, want.col) << "level " << level << ", code " << code;
    };
    for (Code code = 0; code < grid::cell_count(level); ++code) check(code);
    std::mt19937_64 rng(static_cast<unsigned>(level));
    std::uniform_int_distribution<Code> any(0, grid::cell_count(level) - 1);
    for (int n = 0; n < 5000; ++n) check(any(rng));
    for (Code code = 0; code < grid::cell_count(level); code += 1 + any(rng) % 97) check(code);
  }
}

TEST(RegionTracer, OneSiteIsTheWholeRectangle) {
  const int level = 3;
  std::vector<std::int32_t> labels(grid::cell_count(level), 0);
  const auto regions = trace_regions(level, labels.data(), 1);
  ASSERT_EQ(regions[0].size(), 1u);
  EXPECT_TRUE(regions[0][0].holes.empty());
  // Straight runs are dropped: the rectangle's four corners (and the octant corners on the
  // pole lines and on +-180, which are collinear too) leave just the rectangle.
  EXPECT_EQ(regions[0][0].shell.size(), 4u);
  check_regions(level, labels, 1);
}

TEST(RegionTracer, NearestPointRegions) {
  for (int level : {2, 5}) {
    SCOPED_TRACE("level " + std::to_string(level));
    check_regions(level, nearest_point_labels(level, 25, 5), 25);
  }
}

TEST(RegionTracer, RandomLabelsPinchAtVertices) {
  // Every cell a random one of three sites: regions meet themselves at single vertices
  // everywhere, the hardest case for ring linking.
  for (int level : {1, 3, 4}) {
    SCOPED_TRACE("level " + std::to_string(level));
    std::mt19937_64 rng(level);
    std::uniform_int_distribution<std::int32_t> site(0, 2);
    std::vector<std::int32_t> labels(grid::cell_count(level));
    for (auto& l : labels) l = site(rng);
    check_regions(level, labels, 3);
  }
}

TEST(RegionTracer, HolesTouchingTheirShellOrEachOtherAtAVertex) {
  // Site 0 on most cells, so that it is one region full of holes (site 1's cells) that touch one
  // another and the border of the map at single vertices: a ring must never visit a vertex twice.
  for (int level : {3, 5}) {
    SCOPED_TRACE("level " + std::to_string(level));
    std::mt19937_64 rng(100 + level);
    std::bernoulli_distribution other(0.3);
    std::vector<std::int32_t> labels(grid::cell_count(level));
    for (auto& l : labels) l = other(rng) ? 1 : 0;
    check_regions(level, labels, 2);
  }
}

TEST(RegionTracer, IslandInALakeInAnIsland) {
  // Site 0 everywhere, site 1 in a cap around (10, 10), site 0 again in a smaller cap inside:
  // a polygon with a hole, and a second polygon inside that hole.
  const int level = 6;
  const grid::Vec3 centre = grid::unit_vector(10, 10);
  std::vector<std::int32_t> labels(grid::cell_count(level));
  for (Code code = 0; code < labels.size(); ++code) {
    const double d = grid::chord2(grid::cell_centre_vector(code, level), centre);
    labels[code] = (d < 0.01 || d > 0.05) ? 0 : 1;
  }
  const auto regions = trace_regions(level, labels.data(), 2);
  ASSERT_EQ(regions[0].size(), 2u);
  ASSERT_EQ(regions[1].size(), 1u);
  EXPECT_EQ(regions[1][0].holes.size(), 1u);
  check_regions(level, labels, 2);
}

TEST(RegionTracer, RejectsLabelsThatAreNotSites) {
  std::vector<std::int32_t> labels(grid::cell_count(1), 0);
  labels[5] = 7;
  EXPECT_THROW(trace_regions(1, labels.data(), 2), std::invalid_argument);
}

}  // namespace
}  // namespace qtmv::write
