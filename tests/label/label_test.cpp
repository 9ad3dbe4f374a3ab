// Tests of the labeller. One body for both devices: the suites are instantiated for "cpu" and
// for "cuda"; the CUDA ones are skipped when no GPU is usable.
//
// The reference is written here, independently of the labeller's own brute force: it builds
// its candidates from the raw input and orders them with its own key. Only the float64 distance
// of one cell centre to one piece is shared (piece_chord2), and that is tested on its own
// against a long-double geometric construction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "common/device_spec.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_key_ranges.hpp"
#include "label/cpu_painter.hpp"
#include "label/fixed_cover.hpp"
#include "label/label_engine.hpp"
#include "label/synthetic_sites.hpp"
#include "label/label_cuda.hpp"
#include "label/label_math.hpp"
#include "label/label_tree.hpp"
#include "label/labeller.hpp"
#include "label/tree_node_rule.hpp"
#include "cluster_sites.hpp"
#include "wiggly_sites.hpp"

namespace qtmv::label {
namespace {

using grid::Cell;
using grid::Code;

// --- the maths ------------------------------------------------------------------------------

struct LVec {
  long double x, y, z;
};
LVec lv(const Vec3& v) { return {v.x, v.y, v.z}; }
long double ldot(const LVec& a, const LVec& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
LVec lcross(const LVec& a, const LVec& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
long double langle(const LVec& a, const LVec& b) {
  const LVec c = lcross(a, b);
  return std::atan2(std::sqrt(ldot(c, c)), ldot(a, b));
}

// Angle from x to the arc a-b: project x on the arc's plane; if the projection lies between
// a and b (the angles add up), the angle to the plane, else the nearer endpoint.
long double reference_arc_angle(const Vec3& x64, const Vec3& a64, const Vec3& b64) {
  const LVec x = lv(x64), a = lv(a64), b = lv(b64);
  LVec n = lcross(a, b);
  const long double nn = std::sqrt(ldot(n, n));
  n = {n.x / nn, n.y / nn, n.z / nn};
  const long double h = ldot(x, n);
  LVec p{x.x - h * n.x, x.y - h * n.y, x.z - h * n.z};
  const long double pn = std::sqrt(ldot(p, p));
  const long double ends = std::min(langle(x, a), langle(x, b));
  if (pn < 1e-15L) return ends;
  p = {p.x / pn, p.y / pn, p.z / pn};
  const long double ab = langle(a, b), ap = langle(a, p), pb = langle(p, b);
  if (std::fabs(ap + pb - ab) < 1e-12L) return std::min(ends, std::asin(std::min(1.0L, std::fabs(h))));
  return ends;
}

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Vec3 v{g(rng), g(rng), g(rng)};
  const double n = std::sqrt(grid::dot(v, v));
  return {v.x / n, v.y / n, v.z / n};
}

Vec3 slerp_towards(const Vec3& a, const Vec3& dir, double angle) {
  // Rotate a towards dir (projected to a's tangent plane) by angle (radians).
  const double d = grid::dot(a, dir);
  Vec3 t{dir.x - d * a.x, dir.y - d * a.y, dir.z - d * a.z};
  const double tn = std::sqrt(grid::dot(t, t));
  t = {t.x / tn, t.y / tn, t.z / tn};
  Vec3 r{std::cos(angle) * a.x + std::sin(angle) * t.x, std::cos(angle) * a.y + std::sin(angle) * t.y,
         std::cos(angle) * a.z + std::sin(angle) * t.z};
  const double rn = std::sqrt(grid::dot(r, r));
  return {r.x / rn, r.y / rn, r.z / rn};
}

TEST(LabelMath, PointToArcDistanceMatchesGeometry) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_unit(rng);
    const double length = std::pow(10.0, -7.0 + 7.0 * u(rng)) * 1.5;  // 1.5e-7 .. 1.5 rad
    const Vec3 b = slerp_towards(a, random_unit(rng), length);
    // Points near the arc, and anywhere.
    Vec3 x = trial % 2 ? random_unit(rng) : slerp_towards(a, random_unit(rng), length * 3 * u(rng));
    const Piece p = make_arc_piece(a, b, 0);
    const double got = chord2_to_angle(piece_chord2(x, p));
    const long double want = reference_arc_angle(x, a, b);
    ASSERT_NEAR(got, static_cast<double>(want), 1e-12 + 1e-9 * static_cast<double>(want))
        << "trial " << trial << " length " << length;
  }
}

TEST(LabelMath, PointDistanceIsSquaredChord) {
  const Vec3 a = grid::unit_vector(10, 20), x = grid::unit_vector(11, 21);
  EXPECT_EQ(piece_chord2(x, make_point_piece(a, 0)), grid::chord2(x, a));
}

TEST(LabelMath, BetterOrdersByDistanceThenFixedThenSite) {
  const Piece p5 = make_point_piece({1, 0, 0}, 5), p3 = make_point_piece({1, 0, 0}, 3);
  const Piece f7 = make_point_piece({1, 0, 0}, 7, kPieceFixed);
  Best b = no_best();
  consider(b, 0.5, p5);
  consider(b, 0.5, p3);
  EXPECT_EQ(b.site, 3);  // tie: lower id
  consider(b, 0.4, p5);
  EXPECT_EQ(b.site, 5);  // nearer
  consider(b, 0.0, p3);
  consider(b, 0.0, f7);
  EXPECT_EQ(b.site, 7);  // a fixed cell's own centre beats a lower id at distance 0
  Best c = no_best();
  consider(c, 0.2, f7);
  consider(c, 0.2, p3);
  EXPECT_EQ(c.site, 3);  // away from distance 0, fixed pieces are ordinary points
}

// The node bound: every cell centre of a subtree lies within node_radius of the node's centre.
TEST(LabelTree, NodeRadiusBoundsEveryCellCentreOfTheSubtree) {
  const int deepest = 8;
  double worst_ratio = 0;
  for (int level = 1; level <= deepest; ++level) {
    for (Code code = 0; code < grid::cell_count(level); ++code) {
      const Cell c = grid::cell_of(code, level);
      const Vec3 x = grid::cell_centre_vector(code, level);
      for (int to = std::max(0, level - 6); to < level; ++to) {
        const Cell a = grid::ancestor(c, level, to);
        const double r = node_radius(to, a);
        const double d = static_cast<double>(langle(lv(x), lv(grid::cell_centre_vector(grid::code_of(a, to), to))));
        ASSERT_LE(d, r) << "cell " << code << " of level " << level << ", node level " << to;
        worst_ratio = std::max(worst_ratio, d / r);
      }
    }
  }
  // The bound should not be absurdly loose either (it drives the pruning).
  EXPECT_GT(worst_ratio, 0.3);
  RecordProperty("worst_ratio", std::to_string(worst_ratio));
}

// prune_threshold_above keeps every candidate that prune_threshold keeps (it is never below it)
// and is not much above it where it takes its own route (small nodes): over squared chords from 0
// to 4 and radii from 0 to 0.1 radians, the node_radius of every level from 4 to 30 among them.
TEST(LabelMath, RadiusStretchesGiveNodeRadiusStretchBits) {
  // Rows in a pattern of children (r, r + 1, r, r + 1, ...), jumps, and returns to older rows.
  for (int level = 0; level <= 20; level += 4) {
    RadiusStretches stretches;
    const std::uint32_t rows = static_cast<std::uint32_t>(grid::rows_per_octant(level));
    std::mt19937 rng(static_cast<unsigned>(level));
    std::uniform_int_distribution<std::uint32_t> any(0, rows - 1);
    for (int k = 0; k < 4000; ++k) {
      const std::uint32_t row = k % 5 == 4 ? any(rng) : std::min(rows - 1, static_cast<std::uint32_t>(k / 5 + (k & 1)));
      EXPECT_EQ(stretches(level, row), node_radius_stretch(level, row)) << "level " << level << ", row " << row;
    }
  }
}

TEST(LabelMath, PruneThresholdAboveBoundsPruneThreshold) {
  std::vector<double> radii = {0.0, 1e-12, 1e-9, 0.049, 0.05, 0.051, 0.1};
  for (int level = 4; level <= 24; ++level) radii.push_back(node_radius(level, Cell{0, 1, 0}));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> any_chord2(0.0, 4.0);
  std::vector<double> chords2 = {0.0, 1e-18, 1e-12, 1e-6, 0.5, 2.0, 3.89, 3.9, 3.91, 4.0};
  for (int k = 0; k < 2000; ++k) chords2.push_back(any_chord2(rng));
  double worst = 0;  // relative excess where the square-root route is taken
  for (const double r : radii) {
    for (const double c2 : chords2) {
      const double exact = prune_threshold(c2, r), above = prune_threshold_above(c2, r);
      ASSERT_GE(above, exact) << "chord2 " << c2 << " radius " << r;
      if (c2 <= 3.9 && r < 0.05 && exact > 0) worst = std::max(worst, above / exact - 1.0);
    }
  }
  EXPECT_LT(worst, 5e-3);  // cos h <= 1 costs h^2 / 2 at h = 0.05
}

// --- the labelling ----------------------------------------------------------------------------

/// The reference: float64 brute force over the raw input, its own candidate list and ordering.
struct Reference {
  struct Cand {
    Piece piece;
    bool fixed;
  };
  std::vector<Cand> cands;
  int level;

  Reference(const SiteGeometry& g, Rule rule) : level(g.level) {
    if (rule == Rule::exact) {
      for (const SitePiece& p : g.pieces) {
        const bool point = p.a.x == p.b.x && p.a.y == p.b.y && p.a.z == p.b.z;
        cands.push_back({point ? make_point_piece(p.a, p.site) : make_arc_piece(p.a, p.b, p.site), false});
      }
    } else {
      for (const SiteCell& s : g.site_cells) {
        cands.push_back({make_point_piece(grid::cell_centre_vector(s.code, level), s.site), false});
      }
    }
    for (const FixedCell& f : g.fixed_cells) {
      cands.push_back({make_point_piece(grid::cell_centre_vector(f.code, level), f.site), true});
    }
  }

  /// (site, squared chord) of a cell.
  std::pair<std::int32_t, double> label(Code code) const {
    const Vec3 x = grid::cell_centre_vector(code, level);
    double best = 1e300;
    std::int32_t site = -1;
    bool best_fixed = false;
    for (const Cand& c : cands) {
      const double d = piece_chord2(x, c.piece);
      const bool fixed_here = c.fixed && d == 0.0;
      bool take;
      if (d != best) {
        take = d < best;
      } else if (fixed_here != best_fixed) {
        take = fixed_here;
      } else {
        take = c.piece.site < site;
      }
      if (take) {
        best = d;
        site = c.piece.site;
        best_fixed = fixed_here;
      }
    }
    return {site, best};
  }
};

struct SiteSet {
  std::string name;
  SiteGeometry geometry;
};

SiteGeometry random_points(int level, int n, std::uint64_t seed, double lat_min = -90, double lat_max = 90) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180);
  const double zmin = std::sin(lat_min * grid::kDegree), zmax = std::sin(lat_max * grid::kDegree);
  std::uniform_real_distribution<double> z(zmin, zmax);
  SiteGeometry g;
  g.level = level;
  for (int k = 0; k < n; ++k) add_point(g, lon(rng), std::asin(z(rng)) / grid::kDegree, k);
  return g;
}

SiteGeometry duplicates(int level) {
  SiteGeometry g;
  g.level = level;
  const double pts[][2] = {{10, 10}, {-50, 30}, {120, -40}, {10, 10}, {10, 10}, {-50, 30}, {0, 0}, {120, -40}};
  // Ids in an order where the duplicates' lower id comes later in the input.
  int ids[] = {5, 7, 3, 1, 6, 2, 4, 0};
  for (int k = 0; k < 8; ++k) add_point(g, pts[k][0], pts[k][1], ids[k]);
  return g;
}

SiteGeometry poles_and_dateline(int level) {
  SiteGeometry g;
  g.level = level;
  const double pts[][2] = {{0, 90},    {77, 90},  {0, -90},      {-180, 0},   {180, 10},   {179.9999, -5},
                           {-179.9999, -5}, {90, 0}, {-90, 0.0001}, {45, 89.999}, {-135, -89.99}};
  int id = 0;
  for (const auto& p : pts) add_point(g, p[0], p[1], id++);
  return g;
}

SiteGeometry antipodal(int level) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-89, 89);
  for (int k = 0; k < 6; ++k) {
    const double lo = lon(rng), la = lat(rng);
    add_point(g, lo, la, 2 * k + 1);
    add_point(g, lo >= 0 ? lo - 180 : lo + 180, -la, 2 * k);
  }
  return g;
}

SiteGeometry single_site(int level) {
  SiteGeometry g;
  g.level = level;
  add_point(g, 33.3, -12.1, 0);
  return g;
}

/// Pairs of sites straddling cell centres at exactly equal squared chords (the higher id
/// listed first), plus a few random points.
SiteGeometry exact_ties(int level) {
  SiteGeometry g = random_points(level, 6, 5);
  std::mt19937_64 rng(13);
  std::uniform_int_distribution<Code> pick(0, grid::cell_count(level) - 1);
  const double e = std::ldexp(1.0, -40);
  for (int k = 0; k < 8; ++k) {
    const Vec3 c = grid::cell_centre_vector(pick(rng), level);
    // c.z +- e are exact, and so are the differences: both chords are exactly e^2.
    const Vec3 below{c.x, c.y, c.z - e}, above{c.x, c.y, c.z + e};
    const std::int32_t high = 100 + 2 * k, low = 100 + 2 * k - 1 - (k % 2) * 50;
    g.pieces.push_back({above, above, high});
    g.pieces.push_back({below, below, low});
    g.site_count = std::max(g.site_count, high + 1);
  }
  // Site ids not used by any piece are allowed.
  return g;
}

SiteGeometry arcs(int level, int n, double max_degrees, std::uint64_t seed) {
  return test::random_arcs(level, n, max_degrees, seed);
}

/// A "polygon": the cells below one level-2 cell are fixed to a site, with its triangle's edges
/// as arcs of that site; a point of a lower site inside it; a second polygon overlapping the
/// first on some cells with a lower id; and point sites around.
SiteGeometry polygons(int level) {
  SiteGeometry g = random_points(level, 10, 21);
  const int poly = 20, other_poly = 15, inside_point = 3;
  const int shift = std::max(0, level - 2);
  const Code node = 37 % grid::cell_count(2);
  const Cell nc = grid::cell_of(node, 2);
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    const Cell c = grid::cell_of(code, level);
    const Cell a = level >= 2 ? grid::ancestor(c, level, 2) : Cell{-1, 0, 0};
    if (a.octant == nc.octant && a.row == nc.row && a.col == nc.col) {
      add_fixed_cell(g, code, poly);
      if (code % 5 == 0) add_fixed_cell(g, code, other_poly);  // overlap: the lower id wins
    }
  }
  (void)shift;
  grid::LonLat v[3];
  grid::cell_vertices(nc, 2, v);
  for (int k = 0; k < 3; ++k) add_arc(g, v[k].lon, v[k].lat, v[(k + 1) % 3].lon, v[(k + 1) % 3].lat, poly);
  const grid::LonLat centre = grid::cell_centre(nc, 2);
  add_point(g, centre.lon, centre.lat, inside_point);
  return g;
}

/// A polygon whose fixed cells fill the level-2 cell 37 with one site (no overlap), its triangle
/// as arcs of that site, and random points around.
SiteGeometry solid_polygon(int level) {
  SiteGeometry g = random_points(level, 10, 23);
  const int poly = 12;
  const Cell nc = grid::cell_of(37, 2);
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    const Cell a = grid::ancestor(grid::cell_of(code, level), level, 2);
    if (a.octant == nc.octant && a.row == nc.row && a.col == nc.col) add_fixed_cell(g, code, poly);
  }
  grid::LonLat v[3];
  grid::cell_vertices(nc, 2, v);
  for (int k = 0; k < 3; ++k) add_arc(g, v[k].lon, v[k].lat, v[(k + 1) % 3].lon, v[(k + 1) % 3].lat, poly);
  return g;
}

// The cover look-up both builds use (cover_lookup over make_fixed_cover's key ranges) against
// the definition, on every node of every level: a node is covered when all its cells are claimed
// and the lowest claimant of each is one site, partly covered when some but not all are so.
TEST(LabelTree, CoverLookupMatchesEveryNode) {
  const int level = 5;
  SiteGeometry g = solid_polygon(level);
  for (const FixedCell& f : polygons(level).fixed_cells) g.fixed_cells.push_back(f);  // overlaps some
  // A second solid node, one of its cells claimed twice by its own site; scattered cells; and
  // fixed nodes, overlapping cells and each other.
  const Cell other = grid::cell_of(5, 2);
  std::mt19937_64 rng(13);
  for (Code code = 0; code < grid::cell_count(level); ++code) {
    const Cell a = grid::ancestor(grid::cell_of(code, level), level, 2);
    if (a.octant == other.octant && a.row == other.row && a.col == other.col) {
      g.fixed_cells.push_back({code, 4});
      if (code % 61 == 0) g.fixed_cells.push_back({code, 4});
    } else if (rng() % 7 == 0) {
      g.fixed_cells.push_back({code, static_cast<std::int32_t>(rng() % 3)});
    }
  }
  for (int k = 0; k < 40; ++k) {
    const int l = 1 + static_cast<int>(rng() % 4);
    g.fixed_nodes.push_back({rng() % grid::cell_count(l), l, static_cast<std::int32_t>(rng() % 6)});
  }
  std::shuffle(g.fixed_cells.begin(), g.fixed_cells.end(), rng);
  const FixedCover cover = make_fixed_cover(g.input());
  const CoverView view = cover.view();
  // The definition: per cell of the level, its lowest claimant (-1: none).
  std::vector<std::int32_t> lowest(grid::cell_count(level), -1);
  auto claim = [&](std::uint64_t key, std::int32_t site) {
    if (lowest[key] < 0 || site < lowest[key]) lowest[key] = site;
  };
  for (const FixedCell& f : g.fixed_cells) claim(grid::quadtree_key(grid::cell_of(f.code, level), level), f.site);
  for (const FixedNode& n : g.fixed_nodes) {
    const grid::KeyRange r = grid::node_key_range(grid::cell_of(n.code, n.level), n.level, level, n.site);
    for (std::uint64_t q = r.first; q <= r.last; ++q) claim(q, n.site);
  }
  std::uint64_t covered_nodes = 0, partly_nodes = 0;
  for (int l = 0; l <= level; ++l) {
    const int k = level - l;
    for (Code code = 0; code < grid::cell_count(l); ++code) {
      const Cell c = grid::cell_of(code, l);
      const std::uint64_t first = grid::quadtree_key(c, l) << (2 * k);
      std::int32_t want = lowest[first], claimant = -2;  // -2: none yet
      bool any = false;
      for (std::uint64_t q = first; q < first + (std::uint64_t{1} << (2 * k)); ++q) {
        any = any || lowest[q] >= 0;
        if (lowest[q] != want) want = -1;
        if (lowest[q] >= 0) claimant = claimant == -2 || claimant == lowest[q] ? lowest[q] : -1;
      }
      const CoverLookup got = cover_lookup(view, c, l);
      ASSERT_EQ(got.site, want) << "level " << l << " code " << code;
      ASSERT_EQ(got.partly, any && want < 0) << "level " << l << " code " << code;
      ASSERT_EQ(got.claim_site, any ? claimant : -1) << "level " << l << " code " << code;
      covered_nodes += want >= 0 && l < level;
      partly_nodes += got.partly;
    }
  }
  EXPECT_GT(covered_nodes, 4u);
  EXPECT_GT(partly_nodes, 4u);
}

// The cells of fixed nodes are fixed cells: labels, distances and flags equal those of the same
// claims given cell by cell (the float64 reference's view), on the CPU and the GPU, whether the
// nodes are coarse (the tree's cover) or finer than its list level (made into cells).
TEST(LabelTree, FixedNodesLabelAsTheirCells) {
  for (const int level : {4, 6, 8}) {
    // Node 37 of level 2 for site 12, its rim cells' edges as arcs of the site (tight around
    // the cells' centres, as the readers' rings are), and points around.
    SiteGeometry nodes = random_points(level, 10, 23);
    const Cell node = grid::cell_of(37, 2);
    const int depth = level - 2;
    for (std::uint32_t m = 0; m < (1u << (2 * depth)); ++m) {
      const Cell c = grid::descendant(node, depth, m);
      Cell nb[3];
      grid::neighbours(c, level, nb);
      bool rim = false;
      for (const Cell& n : nb) {
        const Cell a = grid::ancestor(n, level, 2);
        rim = rim || a.octant != node.octant || a.row != node.row || a.col != node.col;
      }
      if (!rim) continue;
      grid::LonLat v[3];
      grid::cell_vertices(c, level, v);
      for (int e = 0; e < 3; ++e) add_arc(nodes, v[e].lon, v[e].lat, v[(e + 1) % 3].lon, v[(e + 1) % 3].lat, 12);
    }
    nodes.site_count = std::max(nodes.site_count, 14);
    nodes.fixed_nodes.push_back({37, 2, 12});
    // A node and single cells of another site inside it (the lower id keeps them), and a node of
    // a higher id overlapping the first.
    const Cell inner = grid::descendant(grid::cell_of(37, 2), 1, 2);
    nodes.fixed_nodes.push_back({grid::code_of(inner, 3), 3, 5});
    nodes.fixed_nodes.push_back({grid::code_of(grid::descendant(grid::cell_of(37, 2), 1, 0), 3), 3, 13});
    const Cell deep = grid::descendant(grid::cell_of(37, 2), level - 2, 7);
    nodes.fixed_cells.push_back({grid::code_of(deep, level), 3});
    SiteGeometry cells = nodes;
    const std::vector<FixedCell> all = fixed_cells_with_nodes(nodes.input());
    cells.fixed_cells.assign(all.begin(), all.end());
    cells.fixed_nodes.clear();
    for (const char* device : {"cpu", "cuda"}) {
      if (std::string(device) == "cuda" && cuda_device_count() == 0) continue;
      LabelOptions options;
      options.device = device;
      options.algorithm = Algorithm::hier;
      const LabelResult a = label_all(nodes.input(), options);
      const LabelResult b = label_all(cells.input(), options);
      SCOPED_TRACE(std::string(device) + " level " + std::to_string(level));
      EXPECT_TRUE(a.site == b.site);
      EXPECT_TRUE(a.distance_m == b.distance_m);
      EXPECT_TRUE(a.boundary == b.boundary);
      if (level <= 6) {  // brute force takes every claimed cell
        options.algorithm = Algorithm::brute;
        const LabelResult c = label_all(nodes.input(), options);
        EXPECT_TRUE(c.site == b.site);
      }
      std::uint64_t fixed_zero = 0;
      for (const FixedCell& f : all) fixed_zero += a.distance_m[f.code] == 0.0f;
      EXPECT_EQ(fixed_zero, all.size());
      EXPECT_EQ(a.site[grid::code_of(deep, level)], 3);
    }
  }
}

// The rule both builds apply to a node.
TEST(LabelTree, NodeRuleKinds) {
  // At the labelling level: the winner, as a list with distances.
  EXPECT_EQ(decide_node(true, false, true, 0, true, 7, -1).kind, kUniform);
  EXPECT_EQ(decide_node(true, true, true, 1, true, 7, -1).kind, kListLeaf);
  // Covered by one site's fixed cells: uniform even with distances.
  const NodeDecision covered = decide_node(false, true, false, 200, false, 3, 9);
  EXPECT_EQ(covered.kind, kUniform);
  EXPECT_EQ(covered.site, 9);
  EXPECT_EQ(decide_node(false, false, false, 5, true, 4, -1).kind, kUniform);
  EXPECT_EQ(decide_node(false, true, false, 5, true, 4, -1).kind, kInternal);
  EXPECT_EQ(decide_node(false, true, false, 1, true, 4, -1).kind, kListLeaf);
  EXPECT_EQ(decide_node(false, true, true, kMaxLeafList, false, 4, -1).kind, kListLeaf);
  EXPECT_EQ(decide_node(false, true, true, kMaxLeafList + 1, false, 4, -1).kind, kInternal);
}

// The cover look-up (cover_lookup) agrees with the host tree's leaves:
// with distances, a leaf above the labelling level is uniform iff its cells are covered by one
// site's fixed cells, that site (overlapping polygons included).
TEST(LabelTree, CoverLeavesAreTheCoverLookUps) {
  for (const SiteGeometry& g : {polygons(6), solid_polygon(5), solid_polygon(7)}) {
    const LabelInput in = g.input();
    const FixedCover cover = make_fixed_cover(in);
    const CoverView view = cover.view();
    for (const Rule rule : {Rule::exact, Rule::cell}) {
      const Tree tree = build_tree(make_candidates(in, rule), g.level, true, 2, {}, &view);
      std::uint64_t covered = 0;
      for (const TreeLeaf& leaf : tree.leaves) {
        if (leaf.level == g.level) continue;
        const TreeNode node = tree.nodes[leaf.node];
        const std::int32_t site = cover_lookup(view, leaf.cell, leaf.level).site;
        EXPECT_EQ(node.count == kUniform ? node.value : -1, site) << "level " << leaf.level;
        covered += site >= 0;
      }
      if (g.level == 7) {
        EXPECT_GT(covered, 0u);
      }
    }
  }
}

struct RunCase {
  Algorithm algorithm;
  Rule rule;
};

std::string describe(const RunCase& rc) {
  return std::string(rc.algorithm == Algorithm::hier ? "hier" : "brute") + "/" +
         (rc.rule == Rule::exact ? "exact" : "cell");
}

class LabelDevice : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam().rfind("cuda", 0) == 0 && cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  }

  /// Labels g with every algorithm and rule, and checks labels and distances against the
  /// reference (on every cell, or on `sample` random cells plus every cell of the first
  /// octant row band when sample > 0) and the boundary flags against the neighbours' labels.
  void check_all(const SiteGeometry& g, const std::string& name, std::uint64_t sample = 0,
                 std::vector<RunCase> cases = {{Algorithm::brute, Rule::exact},
                                               {Algorithm::hier, Rule::exact},
                                               {Algorithm::brute, Rule::cell},
                                               {Algorithm::hier, Rule::cell}}) {
    const std::uint64_t cells = grid::cell_count(g.level);
    std::vector<Code> codes;
    if (sample == 0 || sample >= cells) {
      for (Code c = 0; c < cells; ++c) codes.push_back(c);
    } else {
      std::mt19937_64 rng(g.level * 1000 + 17);
      std::uniform_int_distribution<Code> pick(0, cells - 1);
      for (std::uint64_t k = 0; k < sample; ++k) codes.push_back(pick(rng));
    }
    for (const Rule rule : {Rule::exact, Rule::cell}) {
      const Reference ref(g, rule);
      if (rule == Rule::exact && g.pieces.empty() && g.fixed_cells.empty()) continue;
      std::vector<std::pair<std::int32_t, double>> want(codes.size());
      for (std::size_t k = 0; k < codes.size(); ++k) want[k] = ref.label(codes[k]);
      for (const RunCase& rc : cases) {
        if (rc.rule != rule) continue;
        LabelOptions options;
        options.rule = rc.rule;
        options.algorithm = rc.algorithm;
        options.device = GetParam();
        const LabelResult got = label_all(g.input(), options);
        SCOPED_TRACE(name + " level " + std::to_string(g.level) + " " + describe(rc) + " on " + GetParam());
        std::uint64_t wrong = 0;
        for (std::size_t k = 0; k < codes.size(); ++k) {
          const Code code = codes[k];
          if (got.site[code] != want[k].first) {
            if (++wrong <= 5) {
              ADD_FAILURE() << "cell " << code << ": got site " << got.site[code] << ", reference "
                            << want[k].first;
            }
            continue;
          }
          const double metres = chord2_to_metres(want[k].second);
          if (!(std::fabs(got.distance_m[code] - metres) <= 1e-3 + 1e-6 * metres)) {
            if (++wrong <= 5) {
              ADD_FAILURE() << "cell " << code << ": distance " << got.distance_m[code] << " m, reference " << metres;
            }
          }
        }
        EXPECT_EQ(wrong, 0u);
        // Boundary flags: a direct check against the three neighbours' labels, on every cell.
        std::uint64_t bad_boundary = 0;
        for (Code code = 0; code < cells; ++code) {
          Code nb[3];
          grid::neighbours(code, g.level, nb);
          const std::uint8_t flag = got.site[nb[0]] != got.site[code] || got.site[nb[1]] != got.site[code] ||
                                    got.site[nb[2]] != got.site[code];
          if (got.boundary[code] != flag && ++bad_boundary <= 5) {
            ADD_FAILURE() << "cell " << code << ": boundary " << int(got.boundary[code]) << ", neighbours say "
                          << int(flag);
          }
        }
        EXPECT_EQ(bad_boundary, 0u);
      }
    }
  }
};

TEST_P(LabelDevice, RandomPointsAllLevels) {
  for (int level = 0; level <= 9; ++level) {
    const int n = level < 3 ? 7 : 60;
    std::vector<RunCase> cases = {{Algorithm::hier, Rule::exact}, {Algorithm::hier, Rule::cell}};
    if (level <= 7 || GetParam() != "cpu") {
      cases.push_back({Algorithm::brute, Rule::exact});
      cases.push_back({Algorithm::brute, Rule::cell});
    }
    check_all(random_points(level, n, 100 + level), "random", level >= 8 ? 200000 : 0, cases);
  }
}

TEST_P(LabelDevice, ManyPoints) { check_all(random_points(8, 2000, 42), "2000 points", 30000); }

// A tight cluster far from most cells (its points told apart there by the bisector rule), and a
// wider one whose cells lie among its points. Not the cell rule for the tight ones: their cells'
// centres are shared by hundreds of sites (duplicates: every far node keeps them all).
TEST_P(LabelDevice, ClusteredPoints) {
  const std::vector<RunCase> exact = {{Algorithm::hier, Rule::exact}};
  check_all(test::clustered_points(9, 2000, 10, 45, 0.02, 3, 41, 50), "tight cluster", 60000, exact);
  check_all(test::clustered_points(7, 1000, -60, 89.9, 0.05, 3, 42), "cluster at a pole", 0, exact);
  check_all(test::clustered_points(9, 1500, 10, 45, 2.0, 3, 43), "wide cluster", 60000,
            {{Algorithm::hier, Rule::exact}, {Algorithm::hier, Rule::cell}});
}

TEST_P(LabelDevice, Duplicates) {
  for (int level : {0, 1, 4, 7}) check_all(duplicates(level), "duplicates");
}

TEST_P(LabelDevice, PolesAndDateline) {
  for (int level : {0, 2, 5, 8}) check_all(poles_and_dateline(level), "poles", level == 8 ? 100000 : 0);
}

TEST_P(LabelDevice, AntipodalPairs) {
  for (int level : {0, 3, 6}) check_all(antipodal(level), "antipodal");
}

TEST_P(LabelDevice, OneHemisphere) {
  for (int level : {2, 6, 9}) {
    check_all(random_points(level, 40, 77, 5, 80), "hemisphere", level == 9 ? 100000 : 0,
              {{Algorithm::hier, Rule::exact}, {Algorithm::hier, Rule::cell}});
  }
}

TEST_P(LabelDevice, SingleSite) {
  for (int level : {0, 1, 5, 9}) {
    check_all(single_site(level), "single", level == 9 ? 50000 : 0);
  }
}

TEST_P(LabelDevice, ExactTies) {
  for (int level : {3, 6, 9}) {
    const SiteGeometry g = exact_ties(level);
    check_all(g, "ties", level == 9 ? 100000 : 0,
              {{Algorithm::hier, Rule::exact}, {Algorithm::brute, Rule::exact}});
    // Every tie cell goes to the lower id.
    LabelOptions options;
    options.device = GetParam();
    const LabelResult got = label_all(g.input(), options);
    for (std::size_t k = 6; k < g.pieces.size(); k += 2) {
      const Code code = grid::lonlat_to_code(
          std::atan2(g.pieces[k].a.y, g.pieces[k].a.x) / grid::kDegree,
          std::asin(std::max(-1.0, std::min(1.0, g.pieces[k].a.z))) / grid::kDegree, level);
      EXPECT_EQ(got.site[code], std::min(g.pieces[k].site, g.pieces[k + 1].site)) << "tie cell " << code;
    }
  }
}

TEST_P(LabelDevice, Arcs) {
  for (int level : {1, 4, 6}) check_all(arcs(level, 6, 30, 300 + level), "arcs");
  // Lines whose groups have a real reach, seams, turns and long runs (piece_groups.hpp).
  for (int level : {5, 7}) check_all(test::wiggly_sites(level, 700 + level), "wiggly lines");
  check_all(test::wiggly_sites(9, 709), "wiggly lines", 60000, {{Algorithm::hier, Rule::exact}});
  check_all(arcs(8, 4, 6, 388), "arcs", 40000, {{Algorithm::hier, Rule::exact}, {Algorithm::hier, Rule::cell}});
}

TEST_P(LabelDevice, FixedCellsKeepTheirSite) {
  for (int level : {2, 4, 6}) {
    const SiteGeometry g = polygons(level);
    check_all(g, "polygons");
    LabelOptions options;
    options.device = GetParam();
    const LabelResult got = label_all(g.input(), options);
    for (const FixedCell& f : g.fixed_cells) {
      EXPECT_TRUE(got.site[f.code] == 15 || got.site[f.code] == 20) << f.code;
      EXPECT_EQ(got.distance_m[f.code], 0.0f);
    }
  }
}

// Inside a polygon every cell is a fixed cell of its site: the host's tree stops there with
// uniform leaves (distance 0) even when distances are asked for; labels, distances and flags stay
// the reference's on every cell.
TEST_P(LabelDevice, SolidPolygonInteriorsAreUniformLeaves) {
  for (int level : {5, 7}) check_all(solid_polygon(level), "solid polygon");
  const SiteGeometry g = solid_polygon(7);
  const LabelInput in = g.input();
  const std::vector<Piece> candidates = make_candidates(in, Rule::exact);
  const Tree plain = build_tree(candidates, g.level, true, 2);
  const FixedCover cover = make_fixed_cover(in);
  const CoverView view = cover.view();
  const Tree covered = build_tree(candidates, g.level, true, 2, {}, &view);
  std::uint64_t uniform = 0, covered_cells = 0;
  for (const TreeLeaf& leaf : covered.leaves) {
    if (covered.nodes[leaf.node].count != kUniform) continue;
    ++uniform;
    EXPECT_EQ(covered.nodes[leaf.node].value, 12);
    covered_cells += std::uint64_t{1} << (2 * (g.level - leaf.level));
  }
  EXPECT_GT(uniform, 0u);
  EXPECT_LE(covered_cells, g.fixed_cells.size());
  EXPECT_GT(covered_cells, g.fixed_cells.size() / 2);  // most of the interior, in large leaves
  EXPECT_LT(covered.nodes.size(), plain.nodes.size());
  for (const TreeLeaf& leaf : plain.leaves) EXPECT_NE(plain.nodes[leaf.node].count, kUniform);
}

// The candidates take the fixed cells by site and quadtree (fixed_cells_in_quadtree_order: a
// copy unless they come in that order); the input's order must not show in the results: the same labels,
// flags and distances (bit for bit) whether the fixed cells come in code order, reversed,
// shuffled or already in quadtree order (no copy), and the float64 reference's on every cell.
TEST_P(LabelDevice, FixedCellOrderDoesNotShow) {
  SiteGeometry g = solid_polygon(7);
  // A second area (site 3) and some cells that both areas claim.
  const Cell other = grid::cell_of(40, 2);
  const std::vector<FixedCell> first_area(g.fixed_cells.begin(), g.fixed_cells.end());
  for (Code code = 0; code < grid::cell_count(7); ++code) {
    const Cell a = grid::ancestor(grid::cell_of(code, 7), 7, 2);
    if (a.octant == other.octant && a.row == other.row && a.col == other.col) add_fixed_cell(g, code, 3);
  }
  for (std::size_t k = 0; k < first_area.size(); k += 97) add_fixed_cell(g, first_area[k].code, 3);
  check_all(g, "two areas");  // against float64 on every cell
  LabelOptions options;
  options.device = GetParam();
  const LabelResult want = label_all(g.input(), options);
  std::vector<FixedCell> fixed(g.fixed_cells.begin(), g.fixed_cells.end());
  std::mt19937_64 rng(77);
  for (int order = 0; order < 3; ++order) {
    if (order == 0) std::reverse(fixed.begin(), fixed.end());
    if (order == 1) std::shuffle(fixed.begin(), fixed.end(), rng);
    if (order == 2) {
      std::sort(fixed.begin(), fixed.end(), [&](const FixedCell& a, const FixedCell& b) {
        return a.site != b.site ? a.site < b.site
                                : grid::quadtree_key(grid::cell_of(a.code, 7), 7) < grid::quadtree_key(grid::cell_of(b.code, 7), 7);
      });
    }
    LabelInput in = g.input();
    in.fixed_cells = fixed.data();
    const LabelResult got = label_all(in, options);
    EXPECT_EQ(got.site, want.site) << "order " << order;
    EXPECT_EQ(got.boundary, want.boundary) << "order " << order;
    EXPECT_EQ(got.distance_m, want.distance_m) << "order " << order;
  }
}

TEST_P(LabelDevice, TilesMatchOneRun) {
  const SiteGeometry g = arcs(8, 5, 20, 808);
  LabelOptions options;
  options.device = GetParam();
  const LabelResult whole = label_all(g.input(), options);
  for (const Algorithm algorithm : {Algorithm::hier, Algorithm::brute}) {
    options.algorithm = algorithm;
    options.memory_limit_bytes = 9 * 50000;  // tiles of 50000 cells
    std::uint64_t next = 0, mismatches = 0;
    const LabelStats stats = label_cells(g.input(), options, [&](const LabelTile& tile) {
      ASSERT_EQ(tile.first, next);
      for (std::uint64_t k = 0; k < tile.count; ++k) {
        mismatches += tile.site[k] != whole.site[tile.first + k] || tile.boundary[k] != whole.boundary[tile.first + k] ||
                      std::fabs(tile.distance_m[k] - whole.distance_m[tile.first + k]) > 1e-3f;
      }
      next += tile.count;
    });
    EXPECT_EQ(next, grid::cell_count(8));
    EXPECT_GT(stats.tiles, 5u);
    EXPECT_EQ(mismatches, 0u);
  }
}

// The sparse products (outline_cells.hpp) are those of the dense labels of every cell: the same
// outline cells with their sites and flags, the same cells per site, for points, lines and
// polygons, both algorithms and rules, in one tile and in many.
TEST_P(LabelDevice, OutlinesAreThoseOfTheDenseLabels) {
  const std::vector<SiteSet> sets = {
      {"points L3", random_points(3, 40, 5)},       {"points L7", random_points(7, 300, 6)},
      {"poles and dateline", poles_and_dateline(6)}, {"one site", random_points(5, 1, 7)},
      {"arcs", arcs(7, 5, 20, 707)},                 {"wiggly lines", test::wiggly_sites(6, 706)},
      {"polygons", polygons(6)},                     {"solid polygon", solid_polygon(7)}};
  for (const SiteSet& set : sets) {
    for (const Algorithm algorithm : {Algorithm::hier, Algorithm::brute}) {
      for (const Rule rule : {Rule::exact, Rule::cell}) {
        for (const std::size_t limit : {std::size_t{0}, std::size_t{5 * 30000}}) {
          SCOPED_TRACE(set.name + (algorithm == Algorithm::hier ? " hier" : " brute") +
                       (rule == Rule::exact ? " exact" : " cell") + (limit ? " tiles" : "") + " on " + GetParam());
          LabelOptions options;
          options.device = GetParam();
          options.algorithm = algorithm;
          options.rule = rule;
          options.want_distance = false;
          options.memory_limit_bytes = limit;
          const LabelResult dense = label_all(set.geometry.input(), options);
          const Outlines want = outlines_of_dense(set.geometry.level, dense.site.data(), dense.boundary.data(),
                                                  set.geometry.site_count);
          Outlines got;
          label_outlines(set.geometry.input(), options, &got);
          EXPECT_NO_THROW(check_outlines(got));
          EXPECT_EQ(got.level, set.geometry.level);
          ASSERT_EQ(got.cells.size(), want.cells.size());
          std::size_t mismatches = 0;
          for (std::size_t k = 0; k < want.cells.size(); ++k) {
            mismatches += got.cells[k].code() != want.cells[k].code() || got.cells[k].site != want.cells[k].site ||
                          got.cells[k].boundary() != want.cells[k].boundary();
          }
          EXPECT_EQ(mismatches, 0u);
          EXPECT_EQ(got.cells_per_site, want.cells_per_site);
          // site_of gives every cell's label from the outline cells alone.
          for (Code code = 0; code < grid::cell_count(got.level); code += 7) {
            ASSERT_EQ(site_of(got.cells, code), dense.site[code]) << code;
          }
        }
      }
    }
  }
}

/// Outline cells that differ between two products (code, site or flag), or the size difference.
std::size_t outline_mismatches(const OutlineCells& got, const OutlineCells& want) {
  if (got.size() != want.size()) return std::max(got.size(), want.size());
  std::size_t mismatches = 0;
  for (std::size_t k = 0; k < want.size(); ++k) {
    mismatches += got[k].code() != want[k].code() || got[k].site != want[k].site || got[k].boundary() != want[k].boundary();
  }
  return mismatches;
}

// A tile whose outline cells do not fit the device's buffer at once gives them in several runs
// of segments (the buffer made small by the tests' switch): the same cells.
TEST_P(LabelDevice, OutlinesInSeveralRunsAreTheSame) {
  if (GetParam() == "cpu") GTEST_SKIP() << "the device's selection only";
  const SiteSet set{"points L8", random_points(8, 2000, 8)};
  LabelOptions options;
  options.device = GetParam();
  options.want_distance = false;
  Outlines whole;
  label_outlines(set.geometry.input(), options, &whole);
  ::setenv("QTMV_FAULT_OUTLINE_BUFFER", "4096", 1);
  Outlines runs;
  label_outlines(set.geometry.input(), options, &runs);
  ::unsetenv("QTMV_FAULT_OUTLINE_BUFFER");
  ASSERT_GT(whole.cells.size(), 3u * 4096) << "too few outline cells for several runs";
  EXPECT_EQ(outline_mismatches(runs.cells, whole.cells), 0u);
  EXPECT_EQ(runs.cells_per_site, whole.cells_per_site);
  const LabelResult dense = label_all(set.geometry.input(), options);
  const Outlines want = outlines_of_dense(set.geometry.level, dense.site.data(), dense.boundary.data(),
                                          set.geometry.site_count);
  EXPECT_EQ(outline_mismatches(runs.cells, want.cells), 0u);
}


/// The device names of a parameter for label_outlines_on ("cuda" is "cuda:0").
std::string device_name(const std::string& param) { return param == "cuda" ? "cuda:0" : param; }

// A level's ranges of whole rows (tile jobs, several GPUs) give products that join, by
// concatenation and addition, into the whole level's: both algorithms and rules, with the
// device's own tiles smaller than the ranges too.
TEST_P(LabelDevice, OutlinesOfRangesJoinIntoTheWhole) {
  const std::vector<SiteSet> sets = {{"points L7", random_points(7, 300, 16)},
                                     {"arcs", arcs(7, 5, 20, 717)},
                                     {"polygons", polygons(6)},
                                     {"solid polygon", solid_polygon(7)},
                                     {"wiggly lines", test::wiggly_sites(6, 716)}};
  // On a GPU the tree is built on the device, or given by the host: then a range's tree is the
  // host's, built for the range only (build_tree's focus).
  const std::vector<bool> tree_places = GetParam() == std::string("cpu") ? std::vector<bool>{true}
                                                                         : std::vector<bool>{true, false};
  for (const SiteSet& set : sets) {
    const int level = set.geometry.level;
    for (const Algorithm algorithm : {Algorithm::hier, Algorithm::brute}) {
      for (const bool tree_on_device : tree_places) {
        if (!tree_on_device && algorithm != Algorithm::hier) continue;
        for (const Rule rule : {Rule::exact, Rule::cell}) {
          LabelOptions options;
          options.device = GetParam();
          options.tree_on_device = tree_on_device;
          options.algorithm = algorithm;
          options.rule = rule;
          Outlines whole;
          label_outlines(set.geometry.input(), options, &whole);
          for (const int parts : {2, 5, 13}) {
            SCOPED_TRACE(set.name + (algorithm == Algorithm::hier ? " hier" : " brute") +
                         (tree_on_device ? "" : " (the host's tree)") + (rule == Rule::exact ? " exact " : " cell ") +
                         std::to_string(parts) + " parts on " + GetParam());
            options.memory_limit_bytes = parts == 5 ? 25 * 8000 : 0;  // device tiles inside the ranges
            Outlines joined;
            joined.cells_per_site.assign(whole.cells_per_site.size(), 0);
            for (int k = 1; k <= parts; ++k) {
              options.range = grid::tile_range(level, k, parts);
              Outlines part;
              label_outlines(set.geometry.input(), options, &part);
              ASSERT_EQ(part.range, options.range);
              ASSERT_NO_THROW(check_outlines(part));
              joined.cells.insert(joined.cells.end(), part.cells.begin(), part.cells.end());
              for (std::size_t s = 0; s < part.cells_per_site.size(); ++s) joined.cells_per_site[s] += part.cells_per_site[s];
            }
            options.range = {};
            EXPECT_EQ(outline_mismatches(joined.cells, whole.cells), 0u);
            EXPECT_EQ(joined.cells_per_site, whole.cells_per_site);
          }
        }
      }
    }
  }
}

// label_outlines_on: several devices at once (several CPU runs on threads; on a GPU, the same
// GPU from several threads) give one device's products, for the whole level and for a range.
TEST_P(LabelDevice, SeveralDevicesGiveOneDevicesOutlines) {
  const SiteGeometry g = arcs(8, 7, 25, 818);
  const std::string device = device_name(GetParam());
  LabelOptions options;
  options.device = GetParam();
  for (const grid::CodeRange range : {grid::CodeRange{}, grid::tile_range(8, 2, 3)}) {
    options.range = range;
    Outlines one;
    label_outlines(g.input(), options, &one);
    for (const std::size_t n : {std::size_t{2}, std::size_t{3}}) {
      SCOPED_TRACE(std::to_string(n) + " x " + device + (range.end ? " on a range" : ""));
      Outlines several;
      double last_fraction = -1;
      options.progress = [&](double f, const char*) {
        EXPECT_GE(f, last_fraction);  // on the calling thread, never backwards
        last_fraction = f;
        return true;
      };
      const LabelStats stats = label_outlines_on(g.input(), options, std::vector<std::string>(n, device), &several);
      options.progress = {};
      EXPECT_NO_THROW(check_outlines(several));
      EXPECT_EQ(several.range, one.range);
      EXPECT_EQ(outline_mismatches(several.cells, one.cells), 0u);
      EXPECT_EQ(several.cells_per_site, one.cells_per_site);
      EXPECT_NE(stats.device.find(", "), std::string::npos) << stats.device;  // every device named
    }
  }
}

// -device lists: cuda:all and cuda:N,M,... parse to the ordinals named, once each; malformed
// lists are refused naming the text; a GPU list on a host without one (or past its count) fails.
TEST(LabelInterface, DeviceListsAreParsedAndChecked) {
  const DeviceSpec all = parse_device_spec("cuda:all");
  EXPECT_TRUE(all.all && all.several() && all.kind == DeviceSpec::Kind::cuda);
  const DeviceSpec two = parse_device_spec("cuda:2,0");
  EXPECT_EQ(two.indices, (std::vector<int>{2, 0}));
  EXPECT_EQ(two.index, 2);
  EXPECT_TRUE(two.several());
  EXPECT_FALSE(parse_device_spec("cuda:1").several());
  EXPECT_EQ(parse_device_spec("cuda").indices, (std::vector<int>{0}));
  for (const std::string bad : {"cuda:", "cuda:0,", "cuda:,1", "cuda:a", "cuda:0;1", "cuda:all,1", "gpu:0"}) {
    EXPECT_THROW(parse_device_spec(bad), std::invalid_argument) << bad;
  }
  try {
    parse_device_spec("cuda:1,1");
    ADD_FAILURE() << "a device named twice was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("twice"), std::string::npos) << e.what();
  }
  const int gpus = cuda_device_count();
  if (gpus == 0) {
    EXPECT_THROW(choose_devices("cuda:all"), std::runtime_error);
    EXPECT_THROW(choose_devices("cuda:0,1"), std::runtime_error);
  } else {
    EXPECT_EQ(choose_devices("cuda:all").size(), static_cast<std::size_t>(gpus));
    EXPECT_THROW(choose_devices("cuda:0," + std::to_string(gpus)), std::runtime_error);
  }
  EXPECT_EQ(choose_devices("cpu").size(), 1u);
  EXPECT_FALSE(choose_devices("cpu").front().cuda);
}

// Several devices stop as one run does: a stop asked for on the calling thread stops them all
// (Interrupted), and one device's failure is the one reported, not the others' stop.
TEST(LabelInterface, SeveralDevicesStopAndFailAsOne) {
  const SiteGeometry g = random_points(8, 500, 919);
  LabelOptions options;
  options.device = "cpu";
  options.progress = [](double, const char*) { return false; };
  Outlines out;
  EXPECT_THROW(label_outlines_on(g.input(), options, {"cpu", "cpu"}, &out), Interrupted);
  options.progress = {};
  std::vector<std::string> said;
  options.messages = [&](Severity, const std::string& m) { said.push_back(m); };
  try {
    label_outlines_on(g.input(), options, {"cpu", "cuda:99"}, &out);
    ADD_FAILURE() << "a missing device was not reported";
  } catch (const Interrupted&) {
    ADD_FAILURE() << "a missing device was reported as a stop";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cuda:99"), std::string::npos) << e.what();
  }
  for (const std::string& m : said) EXPECT_EQ(m.rfind("cpu: ", 0), 0u) << m;  // each names its device
}

// The CPU's tree pass (cpu_tree_outlines), taken whatever share of the cells its list leaves hold,
// gives the outline cells of the dense labels: for points, lines and polygons at levels where the
// tree has uniform leaves of many levels (whose rims it checks edge by edge) and list leaves with
// settled nodes; with the outline pass's coarse jump table and with the full one; for the whole
// level and for ranges joined.
TEST(LabelOutlines, TreePassGivesTheDenseLabelsOutlines) {
  const std::vector<SiteSet> sets = {{"points L9", random_points(9, 40, 21)},
                                     {"points L8", random_points(8, 300, 22)},
                                     {"arcs L8", arcs(8, 5, 20, 708)},
                                     {"wiggly lines L7", test::wiggly_sites(7, 717)},
                                     {"polygons L7", polygons(7)},
                                     {"solid polygon L8", solid_polygon(8)}};
  for (const SiteSet& set : sets) {
    SCOPED_TRACE(set.name);
    const LabelInput in = set.geometry.input();
    const int level = set.geometry.level;
    LabelOptions options;
    options.device = "cpu";
    options.want_distance = false;
    const LabelResult dense = label_all(in, options);
    const Outlines want = outlines_of_dense(level, dense.site.data(), dense.boundary.data(), set.geometry.site_count);
    const std::vector<Piece> candidates = make_candidates(in, Rule::exact);
    const FixedCover cover = make_fixed_cover(in);
    const CoverView view = cover.view();
    for (const JumpTable jump : {JumpTable::outline, JumpTable::full}) {
      SCOPED_TRACE(jump == JumpTable::outline ? "outline jump table" : "full jump table");
      const Tree tree = build_tree(candidates, level, false, 2, {}, &view, jump);
      EXPECT_EQ(tree.jump_level, jump == JumpTable::outline ? tree_outline_jump_level(level) : tree_jump_level(level));
      const TreeView tv = tree.view(candidates.data());
      const grid::CodeRange whole = grid::whole_level(level);
      OutlineCells got = cpu_tree_outlines(tree, tv, 2, whole, {});
      // Three ranges, cut inside octants, joined in order.
      OutlineCells joined;
      const Code cuts[4] = {0, whole.end / 3 + 5, 2 * (whole.end / 3) + 11, whole.end};
      for (int r = 0; r < 3; ++r) {
        const OutlineCells part = cpu_tree_outlines(tree, tv, 2, {cuts[r], cuts[r + 1]}, {});
        joined.insert(joined.end(), part.begin(), part.end());
      }
      for (const OutlineCells* cells : {&got, &joined}) {
        ASSERT_EQ(cells->size(), want.cells.size());
        EXPECT_EQ(outline_mismatches(*cells, want.cells), 0u);
      }
    }
  }
}

// A tree built for a range (a tile job's) gives every cell of the range the whole tree's site,
// distance and boundary flag, and each of their edge neighbours the whole tree's site; its
// outline pass over the range gives the whole tree's outline cells. For ranges of whole rows and
// ranges cut inside rows, with distances (full jump table) and without (the outline pass's
// tree), and it builds a fraction of the whole tree's nodes (about the range's share).
TEST(LabelTree, FocusedTreeLabelsItsRangeAsTheWholeTree) {
  const std::vector<SiteSet> sets = {{"points L8", random_points(8, 300, 23)},
                                     {"arcs L8", arcs(8, 5, 20, 709)},
                                     {"solid polygon L8", solid_polygon(8)}};
  for (const SiteSet& set : sets) {
    const LabelInput in = set.geometry.input();
    const int level = set.geometry.level;
    const std::vector<Piece> candidates = make_candidates(in, Rule::exact);
    const FixedCover cover = make_fixed_cover(in);
    const CoverView view = cover.view();
    const grid::CodeRange all = grid::whole_level(level);
    std::vector<grid::CodeRange> ranges;
    for (const int k : {1, 4, 8}) ranges.push_back(grid::tile_range(level, k, 8));
    ranges.push_back(grid::tile_range(level, 7, 13));
    ranges.push_back({all.end / 3 + 5, 2 * (all.end / 3) + 11});  // cut inside rows
    for (const bool with_distance : {true, false}) {
      const JumpTable jump = with_distance ? JumpTable::full : JumpTable::outline;
      const Tree whole = build_tree(candidates, level, with_distance, 2, {}, &view, jump);
      const TreeView wv = whole.view(candidates.data());
      for (const grid::CodeRange& range : ranges) {
        SCOPED_TRACE(set.name + (with_distance ? " with" : " without") + " distances: codes " +
                     std::to_string(range.first) + " to " + std::to_string(range.end));
        const Tree focused = build_tree(candidates, level, with_distance, 2, {}, &view, jump, range);
        EXPECT_EQ(focused.focus, range);
        // A fraction of the whole tree's nodes: about the range's share of the cells, more where
        // the sites' detail lies in the range (the polygon lies mostly in the third cut in rows).
        const double share = static_cast<double>(range.end - range.first) / static_cast<double>(all.end);
        EXPECT_LT(static_cast<double>(focused.nodes.size()), (share + 0.25) * static_cast<double>(whole.nodes.size()));
        const TreeView fv = focused.view(candidates.data());
        std::uint64_t mismatches = 0, neighbour_mismatches = 0;
        for (Code code = range.first; code < range.end; ++code) {
          std::int32_t site_w, site_f;
          float metres_w = 0, metres_f = 0;
          std::uint8_t boundary_w, boundary_f;
          tree_label_cell(wv, code, &site_w, with_distance ? &metres_w : nullptr, &boundary_w);
          tree_label_cell(fv, code, &site_f, with_distance ? &metres_f : nullptr, &boundary_f);
          mismatches += site_w != site_f || metres_w != metres_f || boundary_w != boundary_f;
          grid::Cell nb[3];
          grid::neighbours(grid::cell_of(code, level), level, nb);
          for (const grid::Cell& n : nb) neighbour_mismatches += tree_label(wv, n) != tree_label(fv, n);
        }
        EXPECT_EQ(mismatches, 0u);
        EXPECT_EQ(neighbour_mismatches, 0u);
        if (with_distance) continue;
        const OutlineCells want = cpu_tree_outlines(whole, wv, 2, range, {});
        const OutlineCells got = cpu_tree_outlines(focused, fv, 2, range, {});
        ASSERT_EQ(got.size(), want.size());
        EXPECT_EQ(outline_mismatches(got, want), 0u);
      }
    }
  }
}

// The counts and flags that outlines_of_dense derives agree with a direct count over the labels.
TEST(LabelOutlines, DenseOutlinesCountEveryCell) {
  const SiteGeometry g = random_points(6, 50, 3);
  LabelOptions options;
  options.device = "cpu";
  const LabelResult dense = label_all(g.input(), options);
  const Outlines o = outlines_of_dense(6, dense.site.data(), nullptr, g.site_count);
  std::vector<std::uint64_t> count(static_cast<std::size_t>(g.site_count), 0);
  std::uint64_t boundary = 0;
  for (Code code = 0; code < grid::cell_count(6); ++code) {
    ++count[static_cast<std::size_t>(dense.site[code])];
    boundary += dense.boundary[code];
  }
  EXPECT_EQ(o.cells_per_site, count);
  std::uint64_t listed_boundary = 0;
  for (const OutlineCell& c : o.cells) listed_boundary += c.boundary();
  EXPECT_EQ(listed_boundary, boundary);  // flags recomputed from the sites equal the labeller's
  EXPECT_EQ(o.cells.size() - listed_boundary + boundary, o.cells.size());
  EXPECT_NO_THROW(check_outlines(o));
  // site_of_near (a search from a given outline cell) agrees with site_of for the cells around
  // each outline cell and for far ones.
  std::mt19937_64 rng(11);
  std::size_t disagree = 0;
  for (std::size_t k = 0; k < o.cells.size(); ++k) {
    Code nb[3];
    grid::neighbours(o.cells[k].code(), 6, nb);
    std::uniform_int_distribution<Code> any(0, grid::cell_count(6) - 1);
    for (const Code c : {nb[0], nb[1], nb[2], any(rng)}) disagree += site_of_near(o.cells, k, c) != site_of(o.cells, c);
  }
  EXPECT_EQ(disagree, 0u);
  // So does NearSearch, which starts from its last answers: asked in code order about each cell's
  // neighbours (its use), then in chunks that start anywhere, and about far cells, which leave
  // its answers behind or ahead of the next cell's.
  for (const std::size_t chunk : {o.cells.size(), std::size_t{37}}) {
    NearSearch search;
    std::vector<std::size_t> firsts;
    for (std::size_t k = 0; k < o.cells.size(); k += chunk) firsts.push_back(k);
    std::shuffle(firsts.begin(), firsts.end(), rng);
    for (const std::size_t first : firsts) {
      for (std::size_t k = first; k < std::min(o.cells.size(), first + chunk); ++k) {
        Code nb[3];
        grid::neighbours(o.cells[k].code(), 6, nb);
        std::uniform_int_distribution<Code> any(0, grid::cell_count(6) - 1);
        for (const Code c : {nb[grid::kNeighbourVertical], any(rng), nb[0], nb[1], nb[2]}) {
          disagree += search.site(o.cells, k, c) != site_of(o.cells, c);
        }
      }
    }
  }
  EXPECT_EQ(disagree, 0u);
  const auto message = [](const Outlines& bad) {
    try {
      check_outlines(bad);
    } catch (const std::logic_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Outlines broken = o;
  broken.cells.erase(broken.cells.begin());  // the first row end
  EXPECT_THROW(check_outlines(broken), std::logic_error);
  // A row end missing anywhere (each thread walks the rows of its share of the cells) is found; a
  // boundary cell inside a row is no row end: its loss is not one.
  std::size_t row_ends_tried = 0, inner_tried = 0;
  for (std::size_t k = 1; k < o.cells.size(); k += 31) {
    const bool row_end = is_row_end(grid::cell_of(o.cells[k].code(), 6));
    Outlines without = o;
    without.cells.erase(without.cells.begin() + static_cast<std::ptrdiff_t>(k));
    if (row_end) {
      ++row_ends_tried;
      EXPECT_NE(message(without).find("row ends missing"), std::string::npos) << k;
    } else {
      ++inner_tried;
      EXPECT_NO_THROW(check_outlines(without)) << k;
    }
  }
  EXPECT_GT(row_ends_tried, 20u);
  EXPECT_GT(inner_tried, 20u);
  // The first broken cell is named (the check runs on all cores).
  Outlines bad_site = o, swapped = o;
  bad_site.cells[o.cells.size() / 2].site = 1000;
  bad_site.cells.back().site = -1;
  EXPECT_NE(message(bad_site).find("site 1000 out of range"), std::string::npos) << message(bad_site);
  std::swap(swapped.cells[7], swapped.cells[8]);
  EXPECT_NE(message(swapped).find("not in increasing order at " + std::to_string(o.cells[7].code())), std::string::npos)
      << message(swapped);
}

TEST_P(LabelDevice, WithoutDistanceOrBoundary) {
  const SiteGeometry g = random_points(7, 100, 9);
  LabelOptions options;
  options.device = GetParam();
  const LabelResult full = label_all(g.input(), options);
  options.want_distance = false;
  options.want_boundary = false;
  const LabelResult bare = label_all(g.input(), options);
  EXPECT_TRUE(bare.distance_m.empty());
  EXPECT_TRUE(bare.boundary.empty());
  EXPECT_EQ(bare.site, full.site);
}

// `automatic` takes brute force on a GPU for small work (cells x candidates <= kBruteWorkLimit)
// and the tree otherwise and on the CPU; the labels are those of an explicit choice.
TEST_P(LabelDevice, AutomaticAlgorithm) {
  const bool gpu = GetParam() != "cpu";
  for (const int level : {6, 10}) {
    const SiteGeometry g = random_points(level, 300, 77);
    LabelOptions options;
    options.device = GetParam();
    options.algorithm = Algorithm::automatic;
    const LabelResult chosen = label_all(g.input(), options);
    const bool small = static_cast<double>(grid::cell_count(level)) * 300 <= kBruteWorkLimit;
    EXPECT_EQ(chosen.stats.algorithm, gpu && small ? Algorithm::brute : Algorithm::hier) << "level " << level;
    options.algorithm = Algorithm::hier;
    const LabelResult hier = label_all(g.input(), options);
    EXPECT_EQ(hier.stats.algorithm, Algorithm::hier);
    EXPECT_EQ(chosen.site, hier.site) << "level " << level;
    EXPECT_EQ(chosen.boundary, hier.boundary) << "level " << level;
  }
}

// The tree built on the GPU is the host's tree, node for node and list entry for list entry,
// and labels without distances (the benchmarks' case) agree bit for bit between the devices.
TEST(LabelDeviceTree, MatchesTheHostTree) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  struct Case {
    std::string name;
    SiteGeometry g;
  };
  std::vector<Case> cases;
  for (int level : {0, 1, 3, 6, 9}) cases.push_back({"random", random_points(level, level < 3 ? 7 : 300, 500 + level)});
  cases.push_back({"many", random_points(10, 20000, 61)});
  cases.push_back({"duplicates", duplicates(5)});
  cases.push_back({"poles", poles_and_dateline(8)});
  cases.push_back({"antipodal", antipodal(6)});
  cases.push_back({"hemisphere", random_points(9, 40, 77, 5, 80)});
  cases.push_back({"single", single_site(9)});
  cases.push_back({"ties", exact_ties(9)});
  cases.push_back({"arcs", arcs(6, 6, 30, 306)});
  cases.push_back({"dense arcs", arcs(10, 40, 25, 910)});
  cases.push_back({"wiggly lines", test::wiggly_sites(7, 77)});
  cases.push_back({"wiggly lines", test::wiggly_sites(10, 710)});
  cases.push_back({"polygons", polygons(6)});
  // Fixed cells that fill nodes: uniform leaves above the labelling level in both builds.
  cases.push_back({"solid polygon", solid_polygon(5)});
  cases.push_back({"solid polygon", solid_polygon(7)});
  // A tight cluster: far nodes keep the few points the bisector rule leaves.
  cases.push_back({"cluster", test::clustered_points(10, 2000, 10, 45, 0.02, 3, 520, 50)});
  cases.push_back({"cluster at a pole", test::clustered_points(8, 800, 30, 89.995, 0.02, 3, 521, 40)});
  cases.push_back({"big cluster", test::clustered_points(9, 9000, -70, -20, 0.02, 3, 522, 97)});
  for (const Case& c : cases) {
    for (const Rule rule : {Rule::exact, Rule::cell}) {
      // A cluster's cells' centres are duplicates of hundreds of sites, which no rule drops.
      if (rule == Rule::cell && c.name.find("cluster") != std::string::npos) continue;
      // The input's fixed cells come in code order; make_candidates and the device build each
      // put them in quadtree order (fixed_cells_in_quadtree_order, a radix sort on the device).
      const LabelInput in = c.g.input();
      if (rule == Rule::exact && in.piece_count == 0 && in.fixed_cell_count == 0) continue;
      if (rule == Rule::cell && in.site_cell_count == 0 && in.fixed_cell_count == 0) continue;
      const std::vector<Piece> candidates = make_candidates(in, rule);
      for (const bool with_distance : {false, true}) {
        SCOPED_TRACE(c.name + " level " + std::to_string(c.g.level) + (rule == Rule::exact ? " exact" : " cell") +
                     (with_distance ? " with distances" : ""));
        // With the fixed cells, as label_cells builds them: nodes inside polygons are uniform.
        const FixedCover cover = make_fixed_cover(in);
        const CoverView view = cover.view();
        const Tree host = build_tree(candidates, c.g.level, with_distance, 2, {}, &view);
        // From the host's candidates, and (exact rule) from the input, the pieces made there.
        for (const bool from_input : {false, true}) {
          if (from_input && rule != Rule::exact) continue;
          SCOPED_TRACE(from_input ? "device candidates" : "host candidates");
          std::unique_ptr<cuda::Labeller> built =
              from_input ? std::make_unique<cuda::Labeller>(0, in, with_distance, 0, &view)
                         : std::make_unique<cuda::Labeller>(0, candidates, c.g.level, with_distance, 0, &view);
          const cuda::Labeller& gpu = *built;
          DefaultInitVector<TreeNode> nodes;
          DefaultInitVector<std::int32_t> lists;
          DefaultInitVector<JumpEntry> jump;
          gpu.download_tree(&nodes, &lists, &jump);
          ASSERT_EQ(nodes.size(), host.nodes.size());
          ASSERT_EQ(lists.size(), host.lists.size());
          ASSERT_EQ(jump.size(), host.jump.size());
          EXPECT_EQ(gpu.tree_info().jump_level, host.jump_level);
          std::uint64_t bad = 0;
          for (std::size_t k = 0; k < nodes.size(); ++k) {
            bad += nodes[k].count != host.nodes[k].count || nodes[k].value != host.nodes[k].value;
          }
          EXPECT_EQ(bad, 0u) << "nodes differ";
          EXPECT_TRUE(lists == host.lists) << "lists differ";
          bad = 0;
          for (std::size_t k = 0; k < jump.size(); ++k) {
            bad += jump[k].node != host.jump[k].node || jump[k].level != host.jump[k].level;
          }
          EXPECT_EQ(bad, 0u) << "jump tables differ";
          EXPECT_NEAR(gpu.tree_info().mean_candidates, host.mean_candidates, 1e-9 * host.mean_candidates);
        }
      }
      // Whole runs: CPU (host tree) and CUDA (device tree) give the same labels and flags.
      LabelOptions options;
      options.rule = rule;
      options.want_distance = false;
      options.device = "cpu";
      const LabelResult cpu = label_all(in, options);
      options.device = "cuda";
      const LabelResult gpu = label_all(in, options);
      EXPECT_TRUE(cpu.site == gpu.site) << c.name;
      EXPECT_TRUE(cpu.boundary == gpu.boundary) << c.name;
      if (grid::cell_count(c.g.level) >= 8 * 40000) {
        // Tiles of 40000 cells (5 bytes each): the GPU's jump cells cut by the tiles' ends.
        options.memory_limit_bytes = 5 * 40000;
        std::uint64_t mismatches = 0, tiles = 0;
        label_cells(in, options, [&](const LabelTile& tile) {
          ++tiles;
          for (std::uint64_t k = 0; k < tile.count; ++k) {
            mismatches += tile.site[k] != cpu.site[tile.first + k] || tile.boundary[k] != cpu.boundary[tile.first + k];
          }
        });
        EXPECT_GT(tiles, 5u);
        EXPECT_EQ(mismatches, 0u) << c.name << " in tiles";
        options.memory_limit_bytes = 0;
      }
      options.want_distance = true;
      const LabelResult gpu_d = label_all(in, options);
      options.device = "cpu";
      const LabelResult cpu_d = label_all(in, options);
      EXPECT_TRUE(cpu_d.site == gpu_d.site) << c.name;
      EXPECT_TRUE(cpu_d.distance_m == gpu_d.distance_m) << c.name;
    }
  }
}

// Labels + flags without distances on ranges that start and end anywhere: at odd codes, inside
// the first rows of an octant (rows shorter than a warp's run of codes), across octant
// boundaries, one or a few cells. Labels and flags must be the CPU's. Ranges of 2^21 cells or
// more go through the paint kernel (level 11 here), smaller ones cell by cell.
TEST(LabelDeviceTree, OddRangesMatchTheCpu) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  for (const int level : {2, 5, 8, 11}) {
    const SiteGeometry g = random_points(level, level < 3 ? 5 : 200, 900 + level);
    const LabelInput in = g.input();
    LabelOptions options;
    options.want_distance = false;
    options.device = "cpu";
    const LabelResult cpu = label_all(in, options);
    const std::uint64_t cells = grid::cell_count(level), octant = grid::cells_per_octant(level);
    cuda::Labeller gpu(0, make_candidates(in, Rule::exact), level, false);
    gpu.reserve(cells, false, true);
    const std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges = {
        {0, 1},          {1, 1},           {1, 3},          {2, 7},          {3, 4097},
        {0, cells},      {1, cells - 1},   {5, cells - 10}, {cells - 1, 1},  {cells - 5, 5},
        {octant - 3, 7}, {octant - 1, 2},  {octant - 513, 1031},             {7, 2 * octant - 9},
        {cells / 3, cells / 3 + 1},        {3 * octant + 11, 3 * octant / 2 - 1}};
    for (const auto& r : ranges) {
      const std::uint64_t first = std::min(r.first, cells - 1);
      const std::uint64_t count = std::min(r.second, cells - first);
      if (count == 0) continue;
      gpu.run(first, count, false, true);
      std::vector<std::int32_t> site(count, -7);
      std::vector<std::uint8_t> flag(count, 7);
      gpu.download(0, count, site.data(), nullptr, flag.data());
      std::uint64_t bad = 0;
      for (std::uint64_t k = 0; k < count; ++k) {
        bad += site[k] != cpu.site[first + k] || flag[k] != cpu.boundary[first + k];
      }
      EXPECT_EQ(bad, 0u) << "level " << level << ", codes " << first << " + " << count;
      // Labels alone.
      gpu.run(first, count, false, false);
      std::fill(site.begin(), site.end(), -7);
      gpu.download(0, count, site.data(), nullptr, nullptr);
      bad = 0;
      for (std::uint64_t k = 0; k < count; ++k) bad += site[k] != cpu.site[first + k];
      EXPECT_EQ(bad, 0u) << "level " << level << ", labels only, codes " << first << " + " << count;
    }
  }
}

// A GPU that runs out of memory (fault injection: QTMV_FAULT_CUDA_OOM) never yields other labels:
// a failed tree build or a failure mid-run hands the rest to the CPU, a tile too large for the
// device gives way to smaller tiles; each says so.
TEST(LabelDeviceFaults, OutOfMemoryFallsBackWithTheSameResults) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  const SiteGeometry g = arcs(8, 5, 20, 808);
  LabelOptions cpu_options;
  cpu_options.device = "cpu";
  const LabelResult want = label_all(g.input(), cpu_options);
  for (const std::string step : {"build", "reserve", "run"}) {
    LabelOptions options;
    options.device = "cuda";
    options.algorithm = Algorithm::hier;  // the tree is built on the device (the build step)
    if (step == "run") options.memory_limit_bytes = 9 * 50000;  // tiles of 50000 cells: a run after the first fails
    std::string log;
    options.messages = [&](Severity severity, const std::string& message) {
      log += (severity == Severity::warning ? "warning: " : "") + message + "\n";
    };
    ::setenv("QTMV_FAULT_CUDA_OOM", step.c_str(), 1);
    const LabelResult got = label_all(g.input(), options);
    ::unsetenv("QTMV_FAULT_CUDA_OOM");
    EXPECT_EQ(got.site, want.site) << step;
    EXPECT_EQ(got.boundary, want.boundary) << step;
    std::uint64_t far = 0;
    for (std::size_t k = 0; k < want.distance_m.size(); ++k) far += std::fabs(got.distance_m[k] - want.distance_m[k]) > 1e-3f;
    EXPECT_EQ(far, 0u) << step;
    if (step == "reserve") {
      EXPECT_NE(log.find("warning: the GPU could not hold"), std::string::npos) << log;
      EXPECT_GT(got.stats.tiles, 1u);
      EXPECT_EQ(got.stats.device.find("then cpu"), std::string::npos) << got.stats.device;
    } else {
      EXPECT_NE(log.find("warning: the GPU ran out of memory"), std::string::npos) << log;
      EXPECT_NE(log.find(step == "run" ? "cells 50000 onwards on the CPU" : "labelling on the CPU instead"),
                std::string::npos)
          << log;
      EXPECT_NE(got.stats.device.find("then cpu"), std::string::npos) << got.stats.device;
    }
  }
}

// The device build leaves its scratch idle in the memory pool; an allocation that fails while it
// is there gives it back and tries again (fault injection: the first try fails), and
// release_cached_memory gives it back on request. Labels and flags stay the CPU's.
// The outline pass too: a GPU that runs out of memory before or during the tiles hands the rest
// to the CPU's tree pass, and the outline cells are those of the CPU alone.
TEST(LabelDeviceFaults, OutlinesFallBackWithTheSameResults) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  const SiteGeometry g = arcs(8, 5, 20, 808);
  LabelOptions options;
  options.device = "cpu";
  Outlines want;
  label_outlines(g.input(), options, &want);
  for (const std::string step : {"build", "reserve", "run"}) {
    options.device = "cuda";
    options.algorithm = Algorithm::hier;
    options.memory_limit_bytes = step == "run" ? 25 * 50000 : 0;  // several tiles: a run after the first fails
    ::setenv("QTMV_FAULT_CUDA_OOM", step.c_str(), 1);
    Outlines got;
    const LabelStats stats = label_outlines(g.input(), options, &got);
    ::unsetenv("QTMV_FAULT_CUDA_OOM");
    EXPECT_NO_THROW(check_outlines(got)) << step;
    ASSERT_EQ(got.cells.size(), want.cells.size()) << step;
    std::size_t mismatches = 0;
    for (std::size_t k = 0; k < want.cells.size(); ++k) {
      mismatches += got.cells[k].code() != want.cells[k].code() || got.cells[k].site != want.cells[k].site ||
                    got.cells[k].boundary() != want.cells[k].boundary();
    }
    EXPECT_EQ(mismatches, 0u) << step;
    EXPECT_EQ(got.cells_per_site, want.cells_per_site) << step;
    if (step == "run") {
      EXPECT_NE(stats.device.find("then cpu"), std::string::npos) << stats.device;
    }
  }
}

TEST(LabelDeviceFaults, FailedAllocationGivesThePoolBackAndRetries) {
  if (cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  const int level = 9;
  const SiteGeometry g = random_points(level, 300, 4242);
  const LabelInput in = g.input();
  LabelOptions options;
  options.want_distance = false;
  options.device = "cpu";
  const LabelResult cpu = label_all(in, options);
  const std::uint64_t cells = grid::cell_count(level);
  cuda::Labeller gpu(0, in, false);
  ASSERT_GT(cuda::device_info(0).pool_idle_bytes, 0u) << "the build's scratch is not left in the pool";
  ::setenv("QTMV_FAULT_CUDA_OOM", "allocate", 1);
  EXPECT_NO_THROW(gpu.reserve(cells, false, true));
  ::unsetenv("QTMV_FAULT_CUDA_OOM");
  EXPECT_EQ(cuda::device_info(0).pool_idle_bytes, 0u) << "the failed try did not give the pool back";
  gpu.run(0, cells, false, true);
  std::vector<std::int32_t> site(cells, -7);
  std::vector<std::uint8_t> flag(cells, 7);
  gpu.download(0, cells, site.data(), nullptr, flag.data());
  EXPECT_EQ(site, cpu.site);
  EXPECT_EQ(flag, cpu.boundary);

  const cuda::Labeller again(0, in, false);
  ASSERT_GT(cuda::device_info(0).pool_idle_bytes, 0u);
  cuda::release_cached_memory(0);
  EXPECT_EQ(cuda::device_info(0).pool_idle_bytes, 0u);
}

INSTANTIATE_TEST_SUITE_P(Cpu, LabelDevice, ::testing::Values(std::string("cpu")));
INSTANTIATE_TEST_SUITE_P(Cuda, LabelDevice, ::testing::Values(std::string("cuda")));

// --- the interface ----------------------------------------------------------------------------

TEST(LabelInterface, RejectsBadInput) {
  SiteGeometry g = random_points(3, 5, 1);
  LabelOptions options;
  options.device = "cpu";
  LabelInput in = g.input();
  in.site_count = 3;  // ids 3 and 4 out of range
  EXPECT_THROW(label_all(in, options), std::invalid_argument);
  in = g.input();
  in.level = 25;
  EXPECT_THROW(label_all(in, options), std::invalid_argument);
  options.device = "gpu";
  EXPECT_THROW(label_all(g.input(), options), std::invalid_argument);
  options.device = "cuda:99";
  EXPECT_THROW(label_all(g.input(), options), std::runtime_error);
  if (cuda_device_count() == 0) {
    options.device = "cuda";
    EXPECT_THROW(label_all(g.input(), options), std::runtime_error);
  }
  SiteGeometry empty;
  empty.level = 2;
  options.device = "cpu";
  EXPECT_THROW(label_all(empty.input(), options), std::invalid_argument);
}

TEST(LabelInterface, AutoSaysWhichDevice) {
  const SiteGeometry g = random_points(2, 5, 1);
  LabelOptions options;
  std::string said;
  options.messages = [&](Severity, const std::string& m) { said += m; };
  double last_progress = -1;
  options.progress = [&](double f, const char*) {
    last_progress = f;
    return true;
  };
  const LabelResult r = label_all(g.input(), options);
  EXPECT_NE(said.find(cuda_device_count() > 0 ? "cuda:0" : "cpu"), std::string::npos) << said;
  EXPECT_EQ(last_progress, 1.0);
}

TEST(LabelInterface, ProgressDuringTheTreeBuildCanStopIt) {
  // A caller stops a run by returning false from progress (or by throwing); on the CPU the tree
  // build reports after each level, so the run stops in the build, before any cell is labelled.
  const SiteGeometry g = random_points(8, 200, 3);
  LabelOptions options;
  options.device = "cpu";
  int prepare_calls = 0;
  bool labelled = false;
  options.progress = [&](double f, const char* stage) {
    return !(std::string(stage) == "prepare" && f > 0 && ++prepare_calls == 3);
  };
  EXPECT_THROW(label_cells(g.input(), options, [&](const LabelTile&) { labelled = true; }), Interrupted);
  EXPECT_EQ(prepare_calls, 3);
  EXPECT_FALSE(labelled);
  // A callback's own exception goes through as it is.
  struct Stop {};
  prepare_calls = 0;
  options.progress = [&](double f, const char* stage) -> bool {
    if (std::string(stage) == "prepare" && f > 0 && ++prepare_calls == 3) throw Stop{};
    return true;
  };
  EXPECT_THROW(label_cells(g.input(), options, [&](const LabelTile&) { labelled = true; }), Stop);
  EXPECT_FALSE(labelled);
}

TEST(LabelInterface, TooLittleMemoryIsAClearError) {
  const SiteGeometry g = random_points(6, 5, 1);
  LabelOptions options;
  options.device = "cpu";
  options.memory_limit_bytes = 1000;
  try {
    label_cells(g.input(), options, [](const LabelTile&) {});
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("GiB"), std::string::npos) << e.what();
  }
}

TEST(LabelInterface, ArcsAreCutIntoQuarterEdgePieces) {
  SiteGeometry g;
  g.level = 6;
  add_arc(g, 0, 0, 10, 10, 0);
  const double limit = grid::kPi / 2 / 64 / 4 * (1 + 1e-9);
  EXPECT_GT(g.pieces.size(), 10u);
  for (const SitePiece& p : g.pieces) EXPECT_LE(chord2_to_angle(grid::chord2(p.a, p.b)), limit);
  // Consecutive pieces join.
  for (std::size_t k = 1; k < g.pieces.size(); ++k) {
    EXPECT_EQ(g.pieces[k].a.x, g.pieces[k - 1].b.x);
  }
  EXPECT_FALSE(g.site_cells.empty());
}

}  // namespace
}  // namespace qtmv::label
