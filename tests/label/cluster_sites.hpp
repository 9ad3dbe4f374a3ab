// Point sites in a tight cluster (a dense city by an ocean), for the labeller's tests: far from
// it the tree's nodes cannot tell the cluster's points apart by their distances, only by the
// bisector rule (label_math.hpp, point_never_nearest).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include "grid/qtm.hpp"
#include "label/labeller.hpp"
#include "label/synthetic_sites.hpp"

namespace qtmv::label::test {

/// n points within `degrees` of (lon, lat), every `duplicate_every`-th of them again on the same
/// spot under a lower site id (exact ties; 0: none), then `far` points spread over the globe.
inline SiteGeometry clustered_points(int level, int n, double lon, double lat, double degrees, int far,
                                     std::uint64_t seed, int duplicate_every = 0) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1), any_lon(-180, 180), any_z(-1, 1);
  const double stretch = 1.0 / std::max(0.01, std::cos(lat * grid::kDegree));
  std::int32_t site = 0;
  for (int k = 0; k < n; ++k) {
    const double lo = grid::normalise_lon(lon + degrees * u(rng) * std::min(stretch, 90.0 / degrees));
    const double la = std::max(-90.0, std::min(90.0, lat + degrees * u(rng)));
    add_point(g, lo, la, site + 1);
    if (duplicate_every > 0 && k % duplicate_every == 0) add_point(g, lo, la, site);
    site += 2;
  }
  for (int k = 0; k < far; ++k) add_point(g, any_lon(rng), std::asin(any_z(rng)) / grid::kDegree, site++);
  return g;
}

}  // namespace qtmv::label::test
