// The host's tree build (build_tree: tree_build.cpp over tree_items and tree_point_bins) against
// a reference written here: the plain level-by-level filter, every node testing every item of its
// parent's list (item_bounds against prune_threshold, the bisector rule of its nearest point item,
// refine_kept, decide_node), the algorithm the host built with before the spatial order. The two trees must be the same node for node,
// list entry for list entry (the labels, the device build's comparison and the digests depend on
// it), for points, lines, polygons, fixed nodes and mixtures, at several levels, with and without
// distances, whole and focused, on 1, 2 and 8 threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "grid/qtm.hpp"
#include "label/fixed_cover.hpp"
#include "label/label_engine.hpp"
#include "label/labeller.hpp"
#include "label/synthetic_sites.hpp"
#include "label/tree_node_rule.hpp"
#include "cluster_sites.hpp"
#include "wiggly_sites.hpp"

namespace qtmv::label {
namespace {

using grid::Cell;
using grid::Code;

// --- the reference ----------------------------------------------------------------------------

/// Whether a node of level l is built under `focus` (label_engine.hpp's rule).
bool reference_in_focus(const grid::CodeRange& focus, bool focused, const Cell& cell, int l, int level) {
  if (!focused || grid::rows_meet(focus, cell, l, level)) return true;
  Cell across[3];
  grid::neighbours(cell, l, across);
  for (const Cell& other : across) {
    if (grid::rows_meet(focus, other, l, level)) return true;
  }
  return false;
}

/// The tree by the plain filter: each node of each level, in order, filters its parent's whole
/// list (the octants: the runs' top items in candidate order). Without `bisector`, the rule of
/// before the bisector rule (distance bounds only), for comparison.
Tree reference_tree(const std::vector<Piece>& candidates, int level, bool with_distance, const CoverView* given,
                    JumpTable jump, grid::CodeRange focus = {}, bool bisector = true) {
  Tree t;
  t.level = level;
  t.nodes.resize(grid::kOctants);
  const bool focused = focus.end != 0 && !(focus == grid::whole_level(level));
  if (focused) t.focus = focus;
  const CoverView cover = given ? *given : CoverView{nullptr, nullptr, nullptr, nullptr, 0, level, false};
  const GroupPlan plan = plan_groups(candidates, 1);
  t.groups = make_groups(candidates, plan.spans, 1);
  const PieceGroup* groups = t.groups.empty() ? nullptr : t.groups.data();
  struct Pending {
    Cell cell;
    std::int32_t node;
    std::shared_ptr<const std::vector<std::int32_t>> list;
  };
  std::vector<Pending> pending;
  const auto top = std::make_shared<const std::vector<std::int32_t>>(plan.top_items);
  for (int o = 0; o < grid::kOctants; ++o) pending.push_back({Cell{o, 0, 0}, o, top});
  double weighted = 0;
  for (int l = 0; l <= level && !pending.empty(); ++l) {
    std::vector<Pending> next;
    const double cells_below = std::ldexp(1.0, 2 * (level - l));
    for (const Pending& p : pending) {
      if (!reference_in_focus(focus, focused, p.cell, l, level)) {
        t.nodes[p.node] = {kUniform, 0};
        t.leaves.push_back({p.cell, l, p.node});
        continue;
      }
      const std::vector<std::int32_t>& list = *p.list;
      const auto n = static_cast<std::int32_t>(list.size());
      weighted += n;
      const Vec3 c = grid::cell_centre_vector(p.cell, l);
      const CoverLookup covered = cover_lookup(cover, p.cell, l);
      std::vector<std::int32_t> kept;
      bool one_site = true;
      std::int32_t site = -1;
      if (l == level && covered.site < 0) {
        std::int32_t winner = -1;
        site = best_of_items(c, list.data(), n, candidates.data(), groups, &winner).site;
        if (with_distance) kept.push_back(winner);
      }
      if (l < level && covered.site < 0) {
        const double radius = node_radius(l, p.cell);
        std::vector<double> lb2(list.size());
        std::vector<std::int32_t> sites(list.size());
        double min_ub2 = kChord2Infinity;
        for (std::int32_t k = 0; k < n; ++k) {
          double ub2;
          item_bounds(c, list[k], candidates.data(), groups, &lb2[k], &ub2, &sites[k]);
          min_ub2 = std::min(min_ub2, ub2);
        }
        const double threshold = prune_threshold(min_ub2, radius);
        // The bisector rule: the point items within the threshold that lie wholly beyond the
        // bisector of the nearest of them (least lb2, then least item), or are its exact
        // duplicates of sites no lower than its, go as if beyond it (point_never_nearest).
        auto is_point = [&](std::int32_t k) { return is_point_item(list[k], candidates.data()); };
        std::int32_t a = -1;
        for (std::int32_t k = 0; k < n && bisector; ++k) {
          if (!is_point(k) || !(lb2[k] <= threshold)) continue;
          if (a < 0 || lb2[k] < lb2[a] || (lb2[k] == lb2[a] && list[k] < list[a])) a = k;
        }
        for (std::int32_t k = 0; k < n; ++k) {
          if (!(lb2[k] <= threshold)) continue;
          if (a >= 0 && k != a && is_point(k) &&
              point_never_nearest(c, radius, candidates[list[a]], candidates[list[k]])) {
            continue;
          }
          const std::int32_t count = refine_kept(c, list[k], candidates.data(), groups, radius, threshold, nullptr);
          if (count == 0) continue;
          const std::size_t at = kept.size();
          kept.resize(at + static_cast<std::size_t>(count));
          refine_kept(c, list[k], candidates.data(), groups, radius, threshold, kept.data() + at);
          if (site < 0) site = sites[k];
          one_site = one_site && sites[k] == site;
        }
      }
      const NodeDecision rule =
          decide_node(l == level, with_distance, l >= tree_list_level(level), static_cast<std::uint32_t>(kept.size()),
                      one_site, site, covered.site, covered.partly, cover.split_partly, covered.claim_site);
      if (rule.kind != kInternal) t.leaves.push_back({p.cell, l, p.node});
      if (rule.kind == kUniform) {
        t.nodes[p.node] = {kUniform, rule.site};
      } else if (rule.kind == kListLeaf) {
        t.nodes[p.node] = {static_cast<std::int32_t>(kept.size()), static_cast<std::int32_t>(t.lists.size())};
        t.lists.insert(t.lists.end(), kept.begin(), kept.end());
        weighted += static_cast<double>(kept.size()) * cells_below;
      } else {
        const auto first_child = static_cast<std::int32_t>(t.nodes.size());
        t.nodes[p.node] = {kInternal, first_child};
        t.nodes.resize(t.nodes.size() + 4);
        const auto shared = std::make_shared<const std::vector<std::int32_t>>(std::move(kept));
        Cell kids[4];
        grid::children(p.cell, kids);
        for (int k = 0; k < 4; ++k) next.push_back({kids[k], first_child + k, shared});
      }
    }
    pending.swap(next);
  }
  t.mean_candidates = weighted / static_cast<double>(t.labelled_cells());
  fill_jump_table(t, jump == JumpTable::full ? tree_jump_level(level) : tree_outline_jump_level(level), 1);
  return t;
}

/// How many entries of two trees differ (0: the same tree); the first few are reported.
std::uint64_t tree_differences(const Tree& got, const Tree& want) {
  std::uint64_t bad = 0;
  auto report = [&](const std::string& what) {
    if (++bad <= 5) ADD_FAILURE() << what;
  };
  if (got.level != want.level || got.jump_level != want.jump_level || !(got.focus == want.focus)) report("header");
  if (got.nodes.size() != want.nodes.size()) report("node count " + std::to_string(got.nodes.size()) + " vs " +
                                                    std::to_string(want.nodes.size()));
  if (got.lists.size() != want.lists.size()) report("list entries " + std::to_string(got.lists.size()) + " vs " +
                                                    std::to_string(want.lists.size()));
  if (got.leaves.size() != want.leaves.size() || got.jump.size() != want.jump.size() ||
      got.groups.size() != want.groups.size()) {
    report("leaf, jump or group count");
  }
  if (bad > 0) return bad;
  for (std::size_t k = 0; k < got.nodes.size(); ++k) {
    if (got.nodes[k].count != want.nodes[k].count || got.nodes[k].value != want.nodes[k].value) {
      report("node " + std::to_string(k) + ": " + std::to_string(got.nodes[k].count) + "," +
             std::to_string(got.nodes[k].value) + " vs " + std::to_string(want.nodes[k].count) + "," +
             std::to_string(want.nodes[k].value));
    }
  }
  for (std::size_t k = 0; k < got.lists.size(); ++k) {
    if (got.lists[k] != want.lists[k]) {
      report("list entry " + std::to_string(k) + ": " + std::to_string(got.lists[k]) + " vs " +
             std::to_string(want.lists[k]));
    }
  }
  for (std::size_t k = 0; k < got.leaves.size(); ++k) {
    const TreeLeaf& a = got.leaves[k];
    const TreeLeaf& b = want.leaves[k];
    if (a.node != b.node || a.level != b.level || a.cell.octant != b.cell.octant || a.cell.row != b.cell.row ||
        a.cell.col != b.cell.col) {
      report("leaf " + std::to_string(k));
    }
  }
  for (std::size_t k = 0; k < got.jump.size(); ++k) {
    if (got.jump[k].node != want.jump[k].node || got.jump[k].level != want.jump[k].level) {
      report("jump entry " + std::to_string(k));
    }
  }
  // The groups are made by the same code: their count and spans suffice.
  for (std::size_t k = 0; k < got.groups.size(); ++k) {
    if (got.groups[k].first != want.groups[k].first || got.groups[k].count != want.groups[k].count) {
      report("group " + std::to_string(k));
    }
  }
  if (got.mean_candidates != want.mean_candidates) {
    report("mean candidates " + std::to_string(got.mean_candidates) + " vs " + std::to_string(want.mean_candidates));
  }
  return bad;
}

// --- the sites --------------------------------------------------------------------------------

struct Case {
  std::string name;
  SiteGeometry g;
};

void add_random_points(SiteGeometry& g, int n, std::uint64_t seed, std::int32_t first_site, double lat_min = -90,
                       double lat_max = 90) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180);
  std::uniform_real_distribution<double> z(std::sin(lat_min * grid::kDegree), std::sin(lat_max * grid::kDegree));
  for (int k = 0; k < n; ++k) add_point(g, lon(rng), std::asin(z(rng)) / grid::kDegree, first_site + k);
}

SiteGeometry random_points(int level, int n, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  add_random_points(g, n, seed, 0);
  return g;
}

/// Points crowded into a cap of `degrees` around (lon, lat), some on the very same spot under
/// different sites (exact ties), and a few spread over the globe.
SiteGeometry crowded_points(int level, int n, double lon, double lat, double degrees, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < n; ++k) {
    const double dlat = degrees * u(rng), dlon = degrees * u(rng) / std::cos(lat * grid::kDegree);
    add_point(g, grid::normalise_lon(lon + dlon), std::max(-90.0, std::min(90.0, lat + dlat)), n - 1 - k);
    if (k % 97 == 0) add_point(g, grid::normalise_lon(lon + dlon), std::max(-90.0, std::min(90.0, lat + dlat)), n + k);
  }
  add_random_points(g, 50, seed + 1, 3 * n);
  return g;
}

/// Sites of several points each (consecutive pieces of one site: runs, so group items), some
/// spread over hundreds of kilometres (loose or split as the nodes shrink).
SiteGeometry multipoint_sites(int level, int sites, int per_site, double spread_degrees, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-0.95, 0.95), u(-1, 1);
  for (int s = 0; s < sites; ++s) {
    const double lo = lon(rng), la = std::asin(z(rng)) / grid::kDegree;
    const double d = s % 7 == 0 ? 10 * spread_degrees : spread_degrees;
    for (int k = 0; k < per_site; ++k) add_point(g, grid::normalise_lon(lo + d * u(rng)), la + d * u(rng) * 0.5, s);
  }
  return g;
}

/// Node 37 of level 2 claimed by one site's fixed cells (some also by a lower site), its triangle
/// as arcs of the site, points around; with `as_node`, the claim is a fixed node instead, with a
/// finer node of another site inside it.
SiteGeometry polygon(int level, bool as_node, int points) {
  SiteGeometry g;
  g.level = level;
  add_random_points(g, points, 21, 0);
  const std::int32_t poly = points + 5, other = points + 1;
  const Cell nc = grid::cell_of(37, 2);
  if (as_node) {
    g.fixed_nodes.push_back({37, 2, poly});
    g.fixed_nodes.push_back({grid::code_of(grid::descendant(nc, 1, 2), 3), 3, other});
    g.site_count = std::max(g.site_count, poly + 1);
  } else {
    for (Code code = 0; code < grid::cell_count(level); ++code) {
      const Cell a = grid::ancestor(grid::cell_of(code, level), level, 2);
      if (a.octant != nc.octant || a.row != nc.row || a.col != nc.col) continue;
      add_fixed_cell(g, code, poly);
      if (code % 5 == 0) add_fixed_cell(g, code, other);
    }
  }
  grid::LonLat v[3];
  grid::cell_vertices(nc, 2, v);
  for (int k = 0; k < 3; ++k) add_arc(g, v[k].lon, v[k].lat, v[(k + 1) % 3].lon, v[(k + 1) % 3].lat, poly);
  return g;
}

/// Points, long lines (loose items), multi-point sites and a polygon in one input.
SiteGeometry mixture(int level, int points, std::uint64_t seed) {
  SiteGeometry g = polygon(level, false, points);
  const std::int32_t base = g.site_count + 10;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-60, 60);
  for (int k = 0; k < 6; ++k) {
    const double lo = lon(rng), la = lat(rng);
    add_arc(g, lo, la, grid::normalise_lon(lo + 40), la + 10, base + k);
  }
  for (int s = 0; s < 200; ++s) {
    const double lo = lon(rng), la = lat(rng);
    for (int k = 0; k < 3; ++k) add_point(g, grid::normalise_lon(lo + 0.01 * k), la, base + 10 + s);
  }
  return g;
}

std::vector<Case> small_cases() {
  std::vector<Case> cases;
  for (int level : {0, 1, 2, 3, 5, 7, 9}) {
    cases.push_back({"random points", random_points(level, level < 3 ? 7 : 300, 100 + level)});
  }
  cases.push_back({"one point", random_points(6, 1, 5)});
  cases.push_back({"crowded points", crowded_points(9, 3000, 10, 45, 1.0, 7)});
  cases.push_back({"crowded at a pole", crowded_points(8, 600, 0, 89.5, 0.5, 8)});
  cases.push_back({"multi-point sites", multipoint_sites(8, 2000, 4, 0.05, 9)});
  cases.push_back({"spread multi-point sites", multipoint_sites(7, 300, 6, 3.0, 10)});
  cases.push_back({"arcs", test::random_arcs(6, 6, 30, 306)});
  cases.push_back({"dense arcs", test::random_arcs(9, 400, 2, 910)});
  cases.push_back({"wiggly lines", test::wiggly_sites(7, 77)});
  cases.push_back({"wiggly lines", test::wiggly_sites(9, 710)});
  cases.push_back({"polygon cells", polygon(6, false, 10)});
  cases.push_back({"polygon node", polygon(8, true, 40)});
  cases.push_back({"mixture", mixture(8, 3000, 12)});
  return cases;
}

/// The build against the reference for one input: both rules (where the input has them; the
/// cell rule unless `cell_rule` is false), with and without distances, with the labeller's
/// cover, on `threads`.
void expect_reference_trees(const Case& c, std::vector<int> threads, bool cell_rule = true) {
  const PreparedInput prepared = prepare_input(c.g.input(), true);
  const LabelInput& in = prepared.input;
  const CoverView view = prepared.cover.view();
  for (const Rule rule : {Rule::exact, Rule::cell}) {
    if (rule == Rule::exact && in.piece_count == 0 && in.fixed_cell_count == 0) continue;
    if (rule == Rule::cell && ((in.site_cell_count == 0 && in.fixed_cell_count == 0) || !cell_rule)) continue;
    const std::vector<Piece> candidates = make_candidates(in, rule, 2);
    for (const bool with_distance : {false, true}) {
      const JumpTable jump = with_distance ? JumpTable::full : JumpTable::outline;
      const Tree want = reference_tree(candidates, in.level, with_distance, &view, jump);
      for (const int t : threads) {
        SCOPED_TRACE(c.name + " level " + std::to_string(in.level) + (rule == Rule::exact ? " exact" : " cell") +
                     (with_distance ? " with distances" : "") + ", " + std::to_string(t) + " threads");
        EXPECT_EQ(tree_differences(build_tree(candidates, in.level, with_distance, t, {}, &view, jump), want), 0u);
      }
    }
  }
}

TEST(TreeBuild, EqualsThePlainFilterNodeForNode) {
  // The parts a level is cut into follow the threads: 1, 3 and 8 cut them differently.
  int k = 0;
  for (const Case& c : small_cases()) expect_reference_trees(c, ++k % 4 == 0 ? std::vector<int>{1, 8} : std::vector<int>{1, 3});
}

// Many sites: the coarse levels' lists are filtered block by block, the finer ones item by item
// and then as point bins (tree_items.hpp, tree_point_bins.hpp).
TEST(TreeBuild, ManySitesEqualThePlainFilter) {
  expect_reference_trees({"many points", random_points(9, 60000, 61)}, {2});
  expect_reference_trees({"many points, coarse", random_points(4, 30000, 62)}, {2});
  expect_reference_trees({"many crowded points", crowded_points(10, 8000, -70, -20, 2.0, 63)}, {2});
  expect_reference_trees({"many multi-point sites", multipoint_sites(9, 15000, 3, 0.02, 64)}, {2});
  expect_reference_trees({"big mixture", mixture(9, 30000, 65)}, {2});
}

TEST(TreeBuild, FocusedTreesEqualThePlainFilter) {
  for (const Case& c : {Case{"points", random_points(9, 5000, 71)}, Case{"mixture", mixture(8, 2000, 72)}}) {
    const PreparedInput prepared = prepare_input(c.g.input(), true);
    const CoverView view = prepared.cover.view();
    const int level = prepared.input.level;
    const std::vector<Piece> candidates = make_candidates(prepared.input, Rule::exact, 2);
    const grid::CodeRange all = grid::whole_level(level);
    for (const grid::CodeRange& range : {grid::tile_range(level, 3, 8), grid::CodeRange{all.end / 3 + 5, all.end / 2}}) {
      for (const bool with_distance : {false, true}) {
        const JumpTable jump = with_distance ? JumpTable::full : JumpTable::outline;
        SCOPED_TRACE(c.name + " codes " + std::to_string(range.first) + " to " + std::to_string(range.end));
        const Tree want = reference_tree(candidates, level, with_distance, &view, jump, range);
        EXPECT_EQ(tree_differences(build_tree(candidates, level, with_distance, 2, {}, &view, jump, range), want), 0u);
      }
    }
  }
}

/// The labels of a run over the host's tree (hier, on the CPU, 2 threads) under `rule`.
LabelResult host_tree_labels(const LabelInput& in, Rule rule = Rule::exact) {
  LabelOptions options;
  options.device = "cpu";
  options.algorithm = Algorithm::hier;
  options.rule = rule;
  options.threads = 2;
  return label_all(in, options);
}

// The labels of a run over the new tree against the float64 brute force, cell by cell, for many
// points (the case the spatial order is for).
TEST(TreeBuild, LabelsOfManyPointsAreTheBruteForces) {
  const SiteGeometry g = random_points(8, 40000, 81);
  const LabelInput in = g.input();
  const LabelResult got = host_tree_labels(in);
  const std::vector<Piece> candidates = make_candidates(in, Rule::exact, 2);
  std::mt19937_64 rng(82);
  std::uniform_int_distribution<Code> pick(0, grid::cell_count(in.level) - 1);
  std::uint64_t wrong = 0;
  for (int k = 0; k < 3000; ++k) {
    const Code code = pick(rng);
    const Best want = reference_best(candidates, code, in.level);
    const double metres = chord2_to_metres(want.chord2);
    if (got.site[code] != want.site || !(std::fabs(got.distance_m[code] - metres) <= 1e-3 + 1e-6 * metres)) {
      if (++wrong <= 5) ADD_FAILURE() << "cell " << code << ": site " << got.site[code] << ", brute force " << want.site;
    }
  }
  EXPECT_EQ(wrong, 0u);
}

// --- clustered sites: the bisector rule ----------------------------------------------------------

/// n points within `degrees` of (lon, lat) added to g under sites above its own.
void add_cluster(SiteGeometry& g, int n, double lon, double lat, double degrees, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::int32_t base = g.site_count;
  for (int k = 0; k < n; ++k) add_point(g, lon + degrees * u(rng), lat + degrees * u(rng), base + k);
}

/// Sites of three points each (line runs: group items), all within `degrees` of (lon, lat).
SiteGeometry clustered_multipoint_sites(int level, int sites, double lon, double lat, double degrees,
                                        std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int s = 0; s < sites; ++s) {
    const double lo = lon + degrees * u(rng), la = lat + degrees * u(rng);
    for (int k = 0; k < 3; ++k) add_point(g, lo + 0.2 * degrees * u(rng), la + 0.2 * degrees * u(rng), s);
  }
  add_random_points(g, 3, seed + 1, sites);
  return g;
}

// A tight cluster far from most nodes: only the bisector rule tells its points apart there. Under
// the cell rule a cluster is a few cells' centres, each shared by many sites: exact duplicates,
// which the rule drops but for those of sites below the nearest point's.
TEST(TreeBuild, ClusteredPointsEqualThePlainFilter) {
  for (const int level : {6, 8, 10}) {
    expect_reference_trees({"cluster", test::clustered_points(level, 2000, 10, 45, 0.02, 3, 200 + level, 50)},
                           {1, 2, 8});
  }
  expect_reference_trees({"cluster at a pole", test::clustered_points(7, 800, 30, 89.995, 0.02, 3, 210, 40)}, {1, 2});
  expect_reference_trees({"cluster at a pole", test::clustered_points(9, 800, 30, 89.995, 0.02, 3, 211, 40)},
                         {1, 2, 8});
  expect_reference_trees({"cluster of duplicates", test::clustered_points(6, 500, -120, -33, 0.01, 3, 212, 1)},
                         {1, 2});
  expect_reference_trees({"cluster of duplicates", test::clustered_points(8, 500, -120, -33, 0.01, 3, 212, 1)},
                         {1, 2});
  SiteGeometry lines = test::random_arcs(8, 40, 20, 213);
  add_cluster(lines, 1500, 10, 45, 0.02, 214);
  expect_reference_trees({"cluster and lines", lines}, {1, 2, 8});
  expect_reference_trees({"cluster of multi-point sites", clustered_multipoint_sites(7, 300, 10, 45, 0.02, 215)},
                         {1, 2}, false);
  // Long lists (over kFlatList items): filtered block by block at the coarse levels.
  expect_reference_trees({"big cluster", test::clustered_points(10, 9000, -70, -20, 0.02, 3, 216, 97)}, {2});
  SiteGeometry city = random_points(9, 20000, 217);
  add_cluster(city, 6000, 139.7, 35.7, 0.05, 218);
  expect_reference_trees({"city in a country", city}, {1, 2});
}

// The fix: far from the cluster the nodes keep a few of its points, not all of them.
TEST(TreeBuild, ClusteredPointsKeepShortLists) {
  const SiteGeometry g = test::clustered_points(7, 2000, 10, 45, 0.02, 3, 221);
  const PreparedInput prepared = prepare_input(g.input(), true);
  const CoverView view = prepared.cover.view();
  const std::vector<Piece> candidates = make_candidates(prepared.input, Rule::exact, 2);
  const Tree before = reference_tree(candidates, 7, false, &view, JumpTable::outline, {}, false);
  const Tree after = build_tree(candidates, 7, false, 2, {}, &view, JumpTable::outline);
  EXPECT_LT(after.mean_candidates * 10, before.mean_candidates);
  EXPECT_LT(after.nodes.size() * 10, before.nodes.size());
  // Level 10, as the reproducer (/work/cluster.csv): the old rule's mean was over 100.
  const SiteGeometry g10 = test::clustered_points(10, 2000, 10, 45, 0.02, 3, 222);
  const PreparedInput p10 = prepare_input(g10.input(), true);
  const CoverView v10 = p10.cover.view();
  const Tree t10 = build_tree(make_candidates(p10.input, Rule::exact, 2), 10, true, 2, {}, &v10, JumpTable::full);
  EXPECT_LT(t10.mean_candidates, 10.0);
  std::printf("clustered points: mean candidates at level 7 %.2f before, %.2f after; %zu and %zu nodes; "
              "level 10 with distances %.2f\n", before.mean_candidates, after.mean_candidates, before.nodes.size(),
              after.nodes.size(), t10.mean_candidates);
}

// --- many sites at one point: the bisector rule's exact duplicates ------------------------------

/// n sites at one spot (lon, lat), their ids ascending with their pieces, 5 more there under
/// lower ids after them (duplicates that stay: the nearest point's site is above theirs), and
/// `far` points spread over the globe.
SiteGeometry sites_at_one_point(int level, int n, double lon, double lat, int far, std::uint64_t seed) {
  SiteGeometry g;
  g.level = level;
  for (int k = 0; k < n; ++k) add_point(g, lon, lat, 10 + k);
  for (int k = 0; k < 5; ++k) add_point(g, lon, lat, 9 - k);
  add_random_points(g, far, seed, n + 10);
  return g;
}

/// The polygon's fixed cells (kPieceFixed points under either rule), some of them also the cells
/// of point sites at their very centres (the same bits under the cell rule, another flag).
SiteGeometry polygon_and_points_at_its_cells(int level) {
  SiteGeometry g = polygon(level, false, 10);
  const std::int32_t base = g.site_count + 1;
  for (std::size_t k = 0; k < g.fixed_cells.size(); k += 7) {
    const grid::LonLat p = grid::cell_centre(g.fixed_cells[k].code, level);
    for (int s = 0; s < 3; ++s) add_point(g, p.lon, p.lat, base + 3 * static_cast<std::int32_t>(k) + s);
  }
  return g;
}

TEST(TreeBuild, SitesAtOnePointEqualThePlainFilter) {
  for (const int level : {7, 10}) {
    expect_reference_trees({"sites at one point", sites_at_one_point(level, 3000, 10, 45, 3, 240)}, {1, 2, 8});
  }
  expect_reference_trees({"sites at one point, many others", sites_at_one_point(9, 3000, -70, -20, 20000, 241)}, {2});
  expect_reference_trees({"sites at a pole", sites_at_one_point(8, 1000, 0, 90, 10, 242)}, {1, 2});
  expect_reference_trees({"polygon and points at its cells", polygon_and_points_at_its_cells(8)}, {1, 2, 8});
}

// Far from the spot the nodes keep its first point and the five of lower sites, not all 3005 of
// them, under either rule.
TEST(TreeBuild, SitesAtOnePointKeepShortLists) {
  const SiteGeometry g = sites_at_one_point(7, 3000, 10, 45, 3, 250);
  const PreparedInput prepared = prepare_input(g.input(), true);
  const CoverView view = prepared.cover.view();
  for (const Rule rule : {Rule::exact, Rule::cell}) {
    const std::vector<Piece> candidates = make_candidates(prepared.input, rule, 2);
    const Tree before = reference_tree(candidates, 7, false, &view, JumpTable::outline, {}, false);
    const Tree after = build_tree(candidates, 7, false, 2, {}, &view, JumpTable::outline);
    EXPECT_LT(after.mean_candidates * 50, before.mean_candidates);
    EXPECT_LT(after.mean_candidates, 20.0);
    std::printf("sites at one point (%s rule): mean candidates at level 7 %.2f before, %.2f after; %zu and %zu "
                "nodes\n", rule == Rule::exact ? "exact" : "cell", before.mean_candidates, after.mean_candidates,
                before.nodes.size(), after.nodes.size());
  }
  const SiteGeometry g10 = sites_at_one_point(10, 3000, 10, 45, 3, 251);
  const PreparedInput p10 = prepare_input(g10.input(), true);
  const CoverView v10 = p10.cover.view();
  const Tree t10 = build_tree(make_candidates(p10.input, Rule::exact, 2), 10, true, 2, {}, &v10, JumpTable::full);
  EXPECT_LT(t10.mean_candidates, 20.0);
  EXPECT_LT(t10.lists.size(), 500000u);
  std::printf("sites at one point: level 10 with distances: mean candidates %.2f, %zu nodes, %zu list entries\n",
              t10.mean_candidates, t10.nodes.size(), t10.lists.size());
}

TEST(TreeBuild, LabelsOfSitesAtOnePointAreTheBruteForces) {
  const SiteGeometry g = sites_at_one_point(10, 3000, 10, 45, 3, 260);
  const LabelInput in = g.input();
  for (const Rule rule : {Rule::exact, Rule::cell}) {
    const LabelResult got = host_tree_labels(in, rule);
    const std::vector<Piece> candidates = make_candidates(in, rule, 2);
    std::mt19937_64 rng(261);
    std::uniform_int_distribution<Code> pick(0, grid::cell_count(in.level) - 1);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    std::uint64_t wrong = 0;
    for (int k = 0; k < 4000; ++k) {
      const Code code = k % 2 ? pick(rng) : grid::lonlat_to_code(10 + u(rng), 45 + u(rng), 10);
      const Best want = reference_best(candidates, code, in.level);
      const double metres = chord2_to_metres(want.chord2);
      if (got.site[code] != want.site || !(std::fabs(got.distance_m[code] - metres) <= 1e-3 + 1e-6 * metres)) {
        if (++wrong <= 5) ADD_FAILURE() << "cell " << code << ": site " << got.site[code] << ", brute force " << want.site;
      }
    }
    EXPECT_EQ(wrong, 0u) << (rule == Rule::exact ? "exact" : "cell") << " rule";
  }
}

// The labels over the tree against the float64 brute force on clustered points: cells spread
// over the globe (where the bisector rule prunes) and cells in and around the cluster.
TEST(TreeBuild, LabelsOfClusteredPointsAreTheBruteForces) {
  for (const double degrees : {0.02, 0.5}) {
    const SiteGeometry g = test::clustered_points(10, 2000, 10, 45, degrees, 3, 231, 50);
    const LabelInput in = g.input();
    const LabelResult got = host_tree_labels(in);
    const std::vector<Piece> candidates = make_candidates(in, Rule::exact, 2);
    std::mt19937_64 rng(232);
    std::uniform_int_distribution<Code> pick(0, grid::cell_count(in.level) - 1);
    std::uniform_real_distribution<double> u(-3, 3);
    std::uint64_t wrong = 0;
    for (int k = 0; k < 4000; ++k) {
      const Code code = k % 2 ? pick(rng) : grid::lonlat_to_code(10 + degrees * u(rng), 45 + degrees * u(rng), 10);
      const Best want = reference_best(candidates, code, in.level);
      const double metres = chord2_to_metres(want.chord2);
      if (got.site[code] != want.site || !(std::fabs(got.distance_m[code] - metres) <= 1e-3 + 1e-6 * metres)) {
        if (++wrong <= 5) ADD_FAILURE() << "cell " << code << ": site " << got.site[code] << ", brute force " << want.site;
      }
    }
    EXPECT_EQ(wrong, 0u) << degrees << " degrees";
  }
}

}  // namespace
}  // namespace qtmv::label
