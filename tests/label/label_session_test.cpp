// The labelling session: any range or list of codes gets exactly the labels of label_all
// (site, distance, boundary flag), for points, arcs and fixed cells, with and without distances.
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
