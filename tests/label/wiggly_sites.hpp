// Line sites that exercise the line runs' groups (piece_groups.hpp), for the labeller's tests:
// random arcs; wiggly polylines (random walks of arcs), a site of two separate lines, a zigzag
// that turns back on itself, a polyline longer than 60 degrees, a straight arc, a line duplicated
// under a lower site id (exact ties), fixed cells and points.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include "grid/qtm.hpp"
#include "label/synthetic_sites.hpp"
#include "label/labeller.hpp"

namespace qtmv::label::test {

inline SiteGeometry wiggly_sites(int level, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-70, 70), turn(-40, 40), step(0.2, 3.0);
  auto walk = [&](std::int32_t site, int vertices, double max_turn, double step_scale) {
    double lo = lon(rng), la = lat(rng), heading = turn(rng) * 4;
    for (int v = 0; v < vertices; ++v) {
      heading += turn(rng) * max_turn / 40.0;
      const double d = step(rng) * step_scale;
      const double la2 = std::max(-85.0, std::min(85.0, la + d * std::cos(heading * grid::kDegree)));
      const double lo2 =
          grid::normalise_lon(lo + d * std::sin(heading * grid::kDegree) / std::cos(la * grid::kDegree));
      add_arc(g, lo, la, lo2, la2, site);
      lo = lo2;
      la = la2;
    }
  };
  for (std::int32_t s = 0; s < 6; ++s) walk(s, 12, 40, 1);
  walk(6, 5, 40, 1);
  walk(6, 5, 40, 1);  // a second line of site 6: one run, not tight across the seam
  add_arc(g, 20, -10, 31, 2, 7);
  add_arc(g, -60, 40, -52, 33, 9);
  add_arc(g, -60, 40, -52, 33, 8);  // the same line as site 9: every distance ties
  for (grid::Code c = 100; c < 160; ++c) add_fixed_cell(g, c, 10);
  add_point(g, 100, 10, 11);
  add_point(g, 101, 10, 11);
  // A zigzag that turns back on itself, and a long polyline (its top groups span > 60 degrees).
  for (int k = 0; k < 6; ++k) {
    add_arc(g, 140 + (k % 2) * 3, -20 + 0.3 * k, 140 + ((k + 1) % 2) * 3, -20 + 0.3 * (k + 1), 12);
  }
  walk(13, 12, 5, 8);
  return g;
}

/// n random arcs of 0.5 to max_degrees, an arc across the dateline, one over a pole, and a point
/// site.
inline SiteGeometry random_arcs(int level, int n, double max_degrees, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-1, 1), len(0.5, max_degrees), dir(0, 360);
  for (int k = 0; k < n; ++k) {
    const double lo = lon(rng), la = std::asin(z(rng)) / grid::kDegree;
    // End point: go `len` degrees from (lo, la) in a random direction (small-angle approximation
    // is fine: any end point will do).
    const double d = len(rng), az = dir(rng) * grid::kDegree;
    double la2 = la + d * std::cos(az);
    la2 = std::max(-89.9, std::min(89.9, la2));
    const double lo2 = lo + d * std::sin(az) / std::max(0.1, std::cos(la * grid::kDegree));
    add_arc(g, lo, la, grid::normalise_lon(lo2), la2, k);
  }
  // An arc across the dateline, one over a pole, and a point site.
  add_arc(g, 175, 5, -170, -3, n);
  add_arc(g, 10, 85, -170, 87, n + 1);
  add_point(g, 60, -30, n + 2);
  return g;
}

}  // namespace qtmv::label::test
