// The labelling session: any range or list of codes gets exactly the labels of label_all
// (site, distance, boundary flag), for points, arcs and fixed cells, with and without distances;
// points along parallels the labels of their cells.
#include "label/label_session.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "label/label_tree.hpp"
#include "label/synthetic_sites.hpp"

namespace qtmv::label {
namespace {

/// Points, a few arcs and a patch of fixed cells of one site, at `level`.
SiteGeometry mixed_sites(int level, unsigned seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
  int site = 0;
  for (; site < 12; ++site) add_point(g, lon(rng), std::asin(z(rng)) * 180.0 / M_PI, site);
  for (int k = 0; k < 3; ++k, ++site) {
    const double a = lon(rng), b = std::asin(z(rng)) * 180.0 / M_PI;
    add_arc(g, a, b, a + 20.0, b * 0.5, site);
  }
  // A block of fixed cells (one polygon's interior): the cells of one coarse cell.
  const grid::Code coarse = grid::lonlat_to_code(10.0, 45.0, std::max(0, level - 2));
  for (grid::Code c = 0; c < grid::cell_count(level); ++c) {
    if (grid::code_of(grid::ancestor(grid::cell_of(c, level), level, std::max(0, level - 2)), std::max(0, level - 2)) ==
        coarse) {
      add_fixed_cell(g, c, site);
    }
  }
  ++site;
  return g;
}

void expect_session_equals_label_all(int level, bool with_distance, const char* device = "cpu") {
  SCOPED_TRACE("level " + std::to_string(level) + (with_distance ? " with distances " : " ") + device);
  const SiteGeometry g = mixed_sites(level, 40 + level);
  LabelOptions options;
  options.device = "cpu";
  options.want_distance = with_distance;
  const LabelResult all = label_all(g.input(), options);
  options.device = device;
  const LabelSession session(g.input(), options);
  EXPECT_EQ(session.level(), level);
  EXPECT_EQ(session.has_distance(), with_distance);
  EXPECT_GT(session.memory_bytes(), 0u);
  const std::uint64_t cells = grid::cell_count(level);

  // Ranges of many sizes, with ends anywhere (strips of rows, and odd pieces).
  std::mt19937_64 rng(level);
  std::vector<std::int32_t> site;
  std::vector<float> metres;
  std::vector<std::uint8_t> boundary;
  for (std::uint64_t first = 0; first < cells;) {
    const std::uint64_t count = std::min<std::uint64_t>(cells - first, 1 + rng() % 3000);
    site.assign(count, -7);
    metres.assign(count, -7.0f);
    boundary.assign(count, 7);
    session.label_range(first, count, site.data(), with_distance ? metres.data() : nullptr, boundary.data());
    for (std::uint64_t k = 0; k < count; ++k) {
      const grid::Code code = first + k;
      ASSERT_EQ(site[k], all.site[code]) << "code " << code;
      ASSERT_EQ(boundary[k], all.boundary[code]) << "code " << code;
      if (with_distance) {
        ASSERT_EQ(metres[k], all.distance_m[code]) << "code " << code;
      }
    }
    first += count;
  }

  // Lists: sorted random codes without repeats, and every code in reverse order.
  std::vector<grid::Code> codes;
  for (int k = 0; k < 5000; ++k) codes.push_back(rng() % cells);
  std::sort(codes.begin(), codes.end());
  codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
  std::vector<grid::Code> reversed(cells);
  for (std::uint64_t k = 0; k < cells; ++k) reversed[k] = cells - 1 - k;
  for (const std::vector<grid::Code>* list : {&codes, &reversed}) {
    site.assign(list->size(), -7);
    metres.assign(list->size(), -7.0f);
    boundary.assign(list->size(), 7);
    session.label_codes(list->data(), list->size(), site.data(), with_distance ? metres.data() : nullptr,
                        boundary.data());
    for (std::size_t k = 0; k < list->size(); ++k) {
      const grid::Code code = (*list)[k];
      ASSERT_EQ(site[k], all.site[code]) << "code " << code;
      ASSERT_EQ(boundary[k], all.boundary[code]) << "code " << code;
      if (with_distance) {
        ASSERT_EQ(metres[k], all.distance_m[code]) << "code " << code;
      }
    }
  }
}

TEST(LabelSession, RangesAndListsEqualLabelAllAtLevels3To7) {
  for (int level = 3; level <= 7; ++level) {
    expect_session_equals_label_all(level, true);
    expect_session_equals_label_all(level, false);
  }
}

// On a GPU the ranges are labelled there (the device-built tree) and lists on a host tree built
// on first use: the same labels as the CPU's.
TEST(LabelSession, OnAGpuRangesAndListsEqualTheCpu) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA device";
  for (int level = 3; level <= 7; level += 2) {
    expect_session_equals_label_all(level, true, "cuda");
    expect_session_equals_label_all(level, false, "cuda");
  }
}

/// Sites with ties: two sites at one point (the lower id wins it), two at mirror images across
/// the meridian 0 and the equator (the cells centred on them are equidistant), one at a pole.
SiteGeometry tied_sites(int level, unsigned seed) {
  SiteGeometry g;
  g.level = level;
  add_point(g, 30.0, 0.0, 0);
  add_point(g, -30.0, 0.0, 1);
  add_point(g, 100.0, 20.0, 2);
  add_point(g, 100.0, -20.0, 3);
  add_point(g, 100.0, 20.0, 4);  // on site 2
  add_point(g, 0.0, 90.0, 5);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
  for (int site = 6; site < 6 + 4 * level; ++site) add_point(g, lon(rng), std::asin(z(rng)) * 180.0 / M_PI, site);
  return g;
}

/// One site: every leaf is an octant (level 0), with or without distances.
SiteGeometry one_site(int level) {
  SiteGeometry g;
  g.level = level;
  add_point(g, 12.0, 34.0, 0);
  return g;
}

/// label_parallels against each point's cell (grid::lonlat_to_code) labelled by the per-cell
/// walk (label_codes): the shortcut's runs through uniform leaves, its list leaves' cells tested
/// once, and its boundary flags from leaves whose edges hold their site, bit for bit.
void expect_parallels_equal_each_points_cell(const SiteGeometry& g, bool with_distance, int threads) {
  const int level = g.level;
  SCOPED_TRACE("level " + std::to_string(level) + (with_distance ? " with distances, " : ", ") +
               std::to_string(threads) + " threads");
  LabelOptions options;
  options.device = "cpu";
  options.want_distance = with_distance;
  options.threads = threads;
  const LabelSession session(g.input(), options);
  std::mt19937_64 rng(level * 7 + threads);
  std::uniform_real_distribution<double> any_lat(-90.0, 90.0), any_lon(-180.0, 180.0);
  const double rows_per_octant = static_cast<double>(grid::rows_per_octant(level));
  // Rows: anywhere, at the poles and the equator, and on the parallels between rows of cells.
  std::vector<double> lat{90.0, -90.0, 0.0};
  for (int k = 0; k < 12; ++k) lat.push_back(any_lat(rng));
  for (int k = 0; k < 4; ++k) {
    const double row = static_cast<double>(rng() % grid::rows_per_octant(level));
    lat.push_back(90.0 - 90.0 * row / rows_per_octant);
    lat.push_back(-(90.0 - 90.0 * row / rows_per_octant));
  }
  // Longitudes: pixel centres much coarser than the cells, about as fine and finer; the quadrants'
  // edges; and a list in no order.
  std::vector<std::vector<double>> lon_lists;
  for (const double per_cell : {0.05, 0.7, 3.0}) {
    const std::size_t width = std::max<std::size_t>(3, static_cast<std::size_t>(per_cell * 8 * rows_per_octant));
    std::vector<double> lon(width);
    for (std::size_t x = 0; x < width; ++x) lon[x] = -180.0 + (static_cast<double>(x) + 0.5) * (360.0 / static_cast<double>(width));
    lon_lists.push_back(lon);
  }
  lon_lists.push_back({-180.0, -90.0, -45.0, 0.0, 45.0, 90.0, 135.0, 179.999999});
  std::vector<double> shuffled;
  for (int k = 0; k < 300; ++k) shuffled.push_back(any_lon(rng));
  lon_lists.push_back(shuffled);
  for (const std::vector<double>& lon : lon_lists) {
    const std::size_t points = lat.size() * lon.size();
    std::vector<grid::Code> codes(points);
    for (std::size_t r = 0; r < lat.size(); ++r) {
      for (std::size_t k = 0; k < lon.size(); ++k) codes[r * lon.size() + k] = grid::lonlat_to_code(lon[k], lat[r], level);
    }
    std::vector<std::int32_t> want_site(points), site(points, -7);
    std::vector<float> want_metres(points), metres(points, -7.0f);
    std::vector<std::uint8_t> want_boundary(points), boundary(points, 7);
    session.label_codes(codes.data(), points, want_site.data(), with_distance ? want_metres.data() : nullptr,
                        want_boundary.data());
    session.label_parallels(lat.data(), static_cast<int>(lat.size()), lon.data(), lon.size(), site.data(),
                            with_distance ? metres.data() : nullptr, boundary.data());
    for (std::size_t p = 0; p < points; ++p) {
      ASSERT_EQ(site[p], want_site[p]) << "point " << p << " of " << lon.size() << " a row, cell " << codes[p];
      ASSERT_EQ(boundary[p], want_boundary[p]) << "point " << p << " of " << lon.size() << " a row, cell " << codes[p];
      if (with_distance) {
        ASSERT_EQ(metres[p], want_metres[p]) << "point " << p << " of " << lon.size() << " a row, cell " << codes[p];
      }
    }
    // The labels alone (no boundary flags asked for) are the same.
    std::vector<std::int32_t> site_only(points, -7);
    session.label_parallels(lat.data(), static_cast<int>(lat.size()), lon.data(), lon.size(), site_only.data(), nullptr,
                            nullptr);
    ASSERT_EQ(site_only, want_site);
  }
}

TEST(LabelSession, ParallelsEqualEachPointsCellAtLevels2To9WithTies) {
  for (int level = 2; level <= 9; ++level) {
    for (const bool with_distance : {false, true}) {
      expect_parallels_equal_each_points_cell(mixed_sites(level, 60 + level), with_distance, 2);
      expect_parallels_equal_each_points_cell(tied_sites(level, 70 + level), with_distance, level % 2 == 0 ? 1 : 3);
      expect_parallels_equal_each_points_cell(one_site(level), with_distance, 2);
    }
  }
}

TEST(LabelSession, ParallelsRefuseCoordinatesOutsideTheirRanges) {
  const SiteGeometry g = mixed_sites(4, 1);
  LabelOptions options;
  options.device = "cpu";
  options.want_distance = false;
  const LabelSession session(g.input(), options);
  std::int32_t site[2];
  float metres[2];
  const double lat[1] = {10.0}, bad_lat[1] = {-90.5}, lon[2] = {0.0, 10.0}, bad_lon[2] = {0.0, 180.0};
  EXPECT_NO_THROW(session.label_parallels(lat, 1, lon, 2, site, nullptr, nullptr));
  EXPECT_THROW(session.label_parallels(bad_lat, 1, lon, 2, site, nullptr, nullptr), std::invalid_argument);
  EXPECT_THROW(session.label_parallels(lat, 1, bad_lon, 2, site, nullptr, nullptr), std::invalid_argument);
  EXPECT_THROW(session.label_parallels(lat, 1, lon, 2, site, metres, nullptr), std::invalid_argument);
}

TEST(LabelSession, RefusesCodesOutsideTheLevelAndDistancesNotPrepared) {
  const SiteGeometry g = mixed_sites(4, 1);
  LabelOptions options;
  options.device = "cpu";
  options.want_distance = false;
  const LabelSession session(g.input(), options);
  std::int32_t site[4];
  float metres[4];
  std::uint8_t boundary[4];
  const std::uint64_t cells = grid::cell_count(4);
  EXPECT_THROW(session.label_range(cells - 2, 4, site, nullptr, boundary), std::invalid_argument);
  EXPECT_THROW(session.label_range(0, 4, site, metres, boundary), std::invalid_argument);
  const grid::Code outside[1] = {cells};
  EXPECT_THROW(session.label_codes(outside, 1, site, nullptr, boundary), std::invalid_argument);
  // Bad input is refused as label_cells refuses it.
  SiteGeometry empty;
  empty.level = 4;
  EXPECT_THROW(LabelSession(empty.input(), options), std::invalid_argument);
}

TEST(LabelSession, ProgressFalseStopsTheBuild) {
  const SiteGeometry g = mixed_sites(6, 2);
  LabelOptions options;
  options.device = "cpu";
  options.progress = [](double, const char*) { return false; };
  EXPECT_THROW(LabelSession(g.input(), options), Interrupted);
}

TEST(LabelSession, JumpTableFollowsTheLevelUpTo256MiB) {
  EXPECT_EQ(session_jump_table_bytes(3), grid::cell_count(0) * sizeof(JumpEntry));
  EXPECT_EQ(session_jump_table_bytes(11), grid::cell_count(8) * sizeof(JumpEntry));
  EXPECT_EQ(session_jump_table_bytes(14), std::uint64_t{256} << 20);
  EXPECT_EQ(session_jump_table_bytes(24), std::uint64_t{256} << 20);
}

}  // namespace
}  // namespace qtmv::label
