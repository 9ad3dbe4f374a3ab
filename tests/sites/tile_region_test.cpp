// The region of a tile job's sites (sites/tile_region.hpp) against brute force: the caps hold
// every cell of the tile and its neighbours; the boxes hold every point within each cap's radius
// and reach, across +-180 and over the poles; the nearest point is the nearest; a cap is
// verified exactly when a point lies within its reach, else it reaches as far as its nearest;
// later rounds read only what the rounds before did not.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include "grid/qtm.hpp"
#include "grid/qtm_topology.hpp"
#include "sites/tile_region.hpp"

namespace qtmv::sites {
namespace {

double angle_between(const grid::Vec3& a, const grid::Vec3& b) {
  const grid::Vec3 c = grid::cross(a, b);
  return std::atan2(std::sqrt(grid::dot(c, c)), grid::dot(a, b));
}

/// The point at `angle` (radians) from (lon, lat) (degrees) in direction `azimuth` (radians).
grid::LonLat offset(double lon, double lat, double angle, double azimuth) {
  const double p = lat * M_PI / 180, l = lon * M_PI / 180;
  const double lat2 = std::asin(std::sin(p) * std::cos(angle) + std::cos(p) * std::sin(angle) * std::cos(azimuth));
  const double lon2 = l + std::atan2(std::sin(azimuth) * std::sin(angle) * std::cos(p),
                                     std::cos(angle) - std::sin(p) * std::sin(lat2));
  return {grid::normalise_lon(lon2 * 180 / M_PI), lat2 * 180 / M_PI};
}

bool in_boxes(const std::vector<LonLatBox>& boxes, grid::LonLat p) {
  for (const LonLatBox& b : boxes) {
    if (p.lat >= b.lat0 && p.lat <= b.lat1 && p.lon >= b.lon0 && p.lon <= b.lon1) return true;
  }
  return false;
}

TEST(TileRegion, CapsHoldTheTilesCellsAndTheirNeighbours) {
  const int level = 8;
  for (const auto& [k, n, coarse] : {std::tuple{1, 8, 3}, {3, 5, 5}, {7, 7, 4}, {2, 3, 0}}) {
    const grid::CodeRange range = grid::tile_range(level, k, n);
    const std::vector<RegionCap> caps = tile_caps(range, level, coarse, 0.01);
    ASSERT_FALSE(caps.empty());
    for (grid::Code code = range.first; code < range.end; code += 97) {
      grid::Code around[4];
      around[0] = code;
      grid::neighbours(code, level, around + 1);
      for (const grid::Code c : around) {
        const grid::Vec3 centre = grid::cell_centre_vector(c, level);
        bool held = false;
        for (const RegionCap& cap : caps) held = held || angle_between(cap.centre, centre) <= cap.radius;
        EXPECT_TRUE(held) << "tile " << k << "/" << n << ", cell " << c << " (of " << code << ")";
      }
    }
    for (const RegionCap& cap : caps) EXPECT_DOUBLE_EQ(cap.reach, cap.radius + 0.01);
  }
}

TEST(TileRegion, BoxesHoldEveryPointWithinReach) {
  std::mt19937_64 rng(38);
  std::uniform_real_distribution<double> u(0, 1);
  for (int round = 0; round < 300; ++round) {
    // A few caps anywhere, polar and at +-180 among them, of any size.
    std::vector<RegionCap> caps;
    for (int c = 0; c < 1 + round % 5; ++c) {
      RegionCap cap;
      cap.lon = round % 3 == 0 ? 179.5 - 359 * (c % 2) : u(rng) * 360 - 180;
      cap.lat = round % 4 == 0 ? 88 - 176 * (c % 2) + u(rng) : std::asin(u(rng) * 2 - 1) * 180 / M_PI;
      cap.centre = grid::unit_vector(cap.lon, cap.lat);
      cap.radius = 0.001 + 0.05 * u(rng);
      cap.reach = cap.radius + std::pow(10.0, -3 + 3.5 * u(rng));  // 0.001 .. 3 radians beyond
      cap.octant = c;
      caps.push_back(cap);
    }
    caps.push_back(caps.front());
    caps.back().verified = true;  // verified caps ask for nothing
    caps.back().reach = 10;
    // Rounds that reach farther: each reads what the rounds before did not.
    ReadRegion region(ReadRegion::step_for(caps));
    std::vector<LonLatBox> boxes;
    for (int reading = 0; reading < 3; ++reading) {
      const std::vector<LonLatBox> next = region.next_boxes(caps);
      for (const LonLatBox& b : next) {
        EXPECT_LE(b.lon0, b.lon1);
        EXPECT_GE(b.lon0, -180.0);
        EXPECT_LE(b.lon1, 180.0);
      }
      boxes.insert(boxes.end(), next.begin(), next.end());
      for (const RegionCap& cap : caps) {
        if (cap.verified) continue;
        const double angle = std::min(M_PI, cap.radius + cap.reach);
        for (int k = 0; k < 300; ++k) {
          const grid::LonLat p = offset(cap.lon, cap.lat, angle * (k < 150 ? 1.0 : u(rng)), u(rng) * 2 * M_PI);
          ASSERT_TRUE(in_boxes(boxes, p)) << "round " << round << ", reading " << reading << ": " << p.lon << " "
                                          << p.lat << " within " << angle << " of " << cap.lon << " " << cap.lat;
        }
      }
      // Asked again for the same reach, nothing is left to read.
      EXPECT_TRUE(region.next_boxes(caps).empty());
      for (RegionCap& cap : caps) cap.reach = cap.radius + 1.7 * (cap.reach - cap.radius);
    }
  }
}

TEST(TileRegion, NearestPointAndVerification) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<grid::LonLat> points;
  for (int k = 0; k < 3000; ++k) points.push_back({u(rng) * 60 - 30, std::asin(u(rng) * 2 - 1) * 180 / M_PI});
  points.push_back({179.9, 89.99});
  const PointIndex index(points, 30000);
  std::vector<RegionCap> caps;
  for (int k = 0; k < 300; ++k) {
    RegionCap cap;
    cap.lon = u(rng) * 360 - 180;
    cap.lat = std::asin(u(rng) * 2 - 1) * 180 / M_PI;
    cap.centre = grid::unit_vector(cap.lon, cap.lat);
    double brute = HUGE_VAL;
    for (const grid::LonLat& p : points) brute = std::min(brute, angle_between(cap.centre, grid::unit_vector(p.lon, p.lat)));
    EXPECT_NEAR(index.nearest(cap.centre, cap.lon, cap.lat, 0.001), brute, 1e-12) << cap.lon << " " << cap.lat;
    cap.radius = 0.01;
    cap.reach = cap.radius + 0.05;
    caps.push_back(cap);
  }
  std::vector<RegionCap> checked = caps;
  const std::size_t left = verify_caps(checked, index);
  std::size_t unverified = 0;
  for (std::size_t k = 0; k < caps.size(); ++k) {
    const double nearest = index.nearest(caps[k].centre, caps[k].lon, caps[k].lat, 0.001);
    EXPECT_EQ(checked[k].verified, nearest < 0.05 - 1e-9) << k;
    if (checked[k].verified) continue;
    ++unverified;
    // It reaches next just past its nearest point, which then verifies it.
    EXPECT_GT(checked[k].reach - checked[k].radius, nearest);
    EXPECT_LT(checked[k].reach - checked[k].radius, nearest + 1e-8);
  }
  EXPECT_EQ(left, unverified);
  EXPECT_GT(unverified, 0u);
  EXPECT_EQ(verify_caps(checked, index), 0u);
  // No points: the reach doubles beyond the radius.
  std::vector<RegionCap> alone{caps.front()};
  EXPECT_EQ(verify_caps(alone, PointIndex({}, 1)), 1u);
  EXPECT_DOUBLE_EQ(alone[0].reach - alone[0].radius, 0.1);
}

TEST(TileRegion, CoarseLevelFollowsTheSpacing) {
  EXPECT_EQ(coarse_level(3, 1e6), 3);   // never finer than the level
  EXPECT_EQ(coarse_level(12, 1e6), 9);  // at most 9
  EXPECT_LE(coarse_level(12, 241), 6);
  EXPECT_EQ(coarse_level(12, 1), 2);  // cells of 22 degrees for one site
  EXPECT_NEAR(site_spacing(41252.96) * 180 / M_PI, 1.0, 1e-6);
}

}  // namespace
}  // namespace qtmv::sites
