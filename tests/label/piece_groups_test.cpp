// The line runs' groups (src/label/piece_groups.hpp): the plan's layout, the bounds against the
// pieces they stand for, a node's refinement of a loose group (refine_kept) against the pieces, and
// the branch-and-bound search against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "grid/qtm.hpp"
#include "label/label_engine.hpp"
#include "label/synthetic_sites.hpp"
#include "label/labeller.hpp"
#include "label/piece_groups.hpp"
#include "wiggly_sites.hpp"

namespace qtmv::label {
namespace {

Vec3 unit(double x, double y, double z) {
  const double n = std::sqrt(x * x + y * y + z * z);
  return {x / n, y / n, z / n};
}

/// The point a fraction t of the way along the minor arc a-b.
Vec3 along(const Vec3& a, const Vec3& b, double t) {
  return unit(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z));
}

using test::wiggly_sites;

std::vector<Piece> candidates_of(const SiteGeometry& g) { return make_candidates(g.input(), Rule::exact, 1); }

/// The candidates of g, their plan and their groups.
struct Grouped {
  std::vector<Piece> pieces;
  GroupPlan plan;
  std::vector<PieceGroup> groups;
};
Grouped grouped(const SiteGeometry& g, int threads) {
  Grouped r;
  r.pieces = candidates_of(g);
  r.plan = plan_groups(r.pieces, threads);
  r.groups = make_groups(r.pieces, r.plan.spans, threads);
  return r;
}

TEST(PieceGroups, PlanIsThePreorderOfHalvedRuns) {
  const SiteGeometry g = wiggly_sites(9, 1);
  const std::vector<Piece> pieces = candidates_of(g);
  const GroupPlan plan = plan_groups(pieces, 2);
  // The plan from the sites alone (the device build's way) is the same.
  const GroupPlan by_site = plan_groups(
      static_cast<std::int64_t>(pieces.size()), [&](std::int64_t k) { return pieces[k].site; }, 3);
  ASSERT_EQ(plan.top_items, by_site.top_items);
  ASSERT_EQ(plan.spans.size(), by_site.spans.size());
  for (std::size_t k = 0; k < plan.spans.size(); ++k) {
    EXPECT_EQ(plan.spans[k].first, by_site.spans[k].first);
    EXPECT_EQ(plan.spans[k].count, by_site.spans[k].count);
    EXPECT_EQ(plan.spans[k].size, by_site.spans[k].size);
  }
  // Every piece is in exactly one top item; a group holds one site's consecutive pieces.
  std::int32_t next = 0;
  for (const std::int32_t item : plan.top_items) {
    if (!is_group_item(item)) {
      EXPECT_EQ(item, next);
      ++next;
      continue;
    }
    const GroupSpan& top = plan.spans[item_group(item)];
    EXPECT_EQ(top.first, next);
    next += top.count;
  }
  EXPECT_EQ(next, static_cast<std::int32_t>(pieces.size()));
  EXPECT_EQ(plan.top_items.size(), 14u);  // one run per site: each of sites 0..13 is consecutive
  for (std::size_t k = 0; k < plan.spans.size(); ++k) {
    const GroupSpan& s = plan.spans[k];
    for (std::int32_t p = s.first; p < s.first + s.count; ++p) EXPECT_EQ(pieces[p].site, pieces[s.first].site);
    if (s.size == 1) {
      EXPECT_GE(s.count, 2);
      EXPECT_LE(s.count, kGroupLeafPieces);
      continue;
    }
    ASSERT_GT(s.count, kGroupLeafPieces);
    const GroupSpan& left = plan.spans[k + 1];
    const GroupSpan& right = plan.spans[k + 1 + left.size];
    EXPECT_EQ(left.first, s.first);
    EXPECT_EQ(left.count, s.count / 2);
    EXPECT_EQ(right.first, s.first + s.count / 2);
    EXPECT_EQ(right.count, s.count - s.count / 2);
    EXPECT_EQ(s.size, 1 + left.size + right.size);
  }
}

TEST(PieceGroups, ReachBoundsEveryPointOfEveryPiece) {
  for (const int level : {6, 10}) {
    const auto [pieces, plan, groups] = grouped(wiggly_sites(level, 2 + level), 2);
    std::size_t tight = 0;
    for (const PieceGroup& grp : groups) {
      tight += grp.tight;
      double worst = 0;
      for (std::int32_t p = grp.first; p < grp.first + grp.count; ++p) {
        for (const double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
          const Vec3 y = along(pieces[p].a, pieces[p].b, t);
          worst = std::max(worst, std::sqrt(piece_chord2(y, grp.arc)));
        }
      }
      EXPECT_LE(worst, grp.reach) << "group of " << grp.count << " pieces at " << grp.first;
      EXPECT_GE(grp.spread, grp.reach);
    }
    // The lines' groups are mostly tight (the bounds are useful, not just valid).
    EXPECT_GT(tight, groups.size() / 2) << "level " << level;
  }
}

TEST(PieceGroups, AStraightRunIsTightAndThin) {
  SiteGeometry g;
  g.level = 12;
  add_arc(g, 10, 10, 20, 15, 0);
  const auto [pieces, plan, groups] = grouped(g, 1);
  ASSERT_GT(pieces.size(), 1000u);
  ASSERT_EQ(plan.top_items.size(), 1u);
  const PieceGroup& top = groups[item_group(plan.top_items[0])];
  EXPECT_EQ(top.tight, 1);
  EXPECT_LT(top.reach, 1e-9);  // the pieces lie on the arc's great circle
  EXPECT_EQ(top.count, static_cast<std::int32_t>(pieces.size()));
}

TEST(PieceGroups, PointsAlongARowMakeATightRun) {
  // Fixed cells along a row of level 12 (row 2000 of octant 0 starts at code 2000^2): no piece
  // joins the next, but the steps between them are short, so the run is tight with a cell's slack.
  SiteGeometry g;
  g.level = 12;
  const grid::Code row = 2000ull * 2000ull;
  for (grid::Code c = row; c <= row + 20; ++c) add_fixed_cell(g, c, 0);
  const auto [pieces, plan, groups] = grouped(g, 1);
  ASSERT_EQ(plan.top_items.size(), 1u);
  const PieceGroup& top = groups[item_group(plan.top_items[0])];
  const double step = std::sqrt(grid::chord2(pieces[0].a, pieces[1].a));
  EXPECT_EQ(top.tight, 1);
  EXPECT_GE(top.slack, top.reach + step);
  EXPECT_LT(top.slack, 4 * step);
  // A run across rows (the end of row 2000, the start of row 2001) is not tight as a whole: the
  // step from a row's end to the next row's start is long.
  SiteGeometry rows;
  rows.level = 12;
  for (grid::Code c = row + 3990; c <= row + 4030; ++c) add_fixed_cell(rows, c, 0);
  const Grouped across = grouped(rows, 1);
  EXPECT_GT(across.groups[item_group(across.plan.top_items[0])].slack, 10 * step);
}

TEST(PieceGroups, BoundsHoldAndBranchAndBoundIsBruteForce) {
  for (const int level : {7, 11}) {
    const auto [pieces, plan, groups] = grouped(wiggly_sites(level, 30 + level), 2);
    std::mt19937_64 rng(level);
    std::normal_distribution<double> jitter(0.0, 0.01);
    std::uniform_int_distribution<std::size_t> pick(0, pieces.size() - 1);
    std::normal_distribution<double> n01;
    for (int trial = 0; trial < 4000; ++trial) {
      // Half the points anywhere, half near a piece (where bounds and ties are tight).
      Vec3 x;
      if (trial % 2) {
        x = unit(n01(rng), n01(rng), n01(rng));
      } else {
        const Vec3 p = pieces[pick(rng)].a;
        x = unit(p.x + jitter(rng), p.y + jitter(rng), p.z + jitter(rng));
      }
      // Each group's bounds against its pieces.
      for (std::size_t k = 0; k < groups.size(); ++k) {
        const PieceGroup& grp = groups[k];
        double nearest = 1e300;
        for (std::int32_t p = grp.first; p < grp.first + grp.count; ++p) {
          nearest = std::min(nearest, piece_chord2(x, pieces[p]));
        }
        double lb2, ub2;
        std::int32_t site;
        item_bounds(x, group_item(static_cast<std::int32_t>(k)), pieces.data(), groups.data(), &lb2, &ub2, &site);
        ASSERT_LE(lb2, nearest * (1 + 1e-12) + 1e-15) << "trial " << trial << " group " << k;
        ASSERT_GE(ub2, nearest * (1 - 1e-12) - 1e-15) << "trial " << trial << " group " << k;
        ASSERT_EQ(site, pieces[grp.first].site);
      }
      // The search over the top items picks what consider() over every piece picks.
      Best brute = no_best();
      consider_all(brute, x, pieces.data(), static_cast<std::int64_t>(pieces.size()));
      std::int32_t winner = -1;
      const Best best = best_of_items(x, plan.top_items.data(), static_cast<std::int32_t>(plan.top_items.size()),
                                      pieces.data(), groups.data(), &winner);
      ASSERT_EQ(best.site, brute.site) << "trial " << trial;
      ASSERT_EQ(best.chord2, brute.chord2) << "trial " << trial;
      ASSERT_EQ(best.rank, brute.rank) << "trial " << trial;
      ASSERT_GE(winner, 0);
      EXPECT_EQ(piece_chord2(x, pieces[winner]), best.chord2);
      EXPECT_EQ(pieces[winner].site, best.site);
    }
  }
}

}  // namespace
}  // namespace qtmv::label

namespace qtmv::label {
namespace {

// refine_kept against the pieces themselves: every piece within the threshold of a node's centre
// stays listed (itself, or inside a listed group), nothing listed is beyond it, the groups listed
// are tight enough for the node, the items come in preorder, and counting gives what writing does.
TEST(PieceGroups, RefineKeptKeepsEveryNearPieceAndListsNothingFar) {
  const auto [pieces, plan, groups] = grouped(wiggly_sites(10, 12), 2);
  std::mt19937_64 rng(99);
  std::size_t refined = 0, dropped = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int l = 3 + static_cast<int>(rng() % 6);
    const grid::Cell cell = grid::cell_of(rng() % grid::cell_count(l), l);
    const Vec3 x = grid::cell_centre_vector(cell, l);
    const double radius = node_radius(l, cell);
    double nearest = 1e300;
    for (const Piece& p : pieces) nearest = std::min(nearest, piece_chord2(x, p));
    const double threshold = prune_threshold(nearest, radius);
    for (const std::int32_t top : plan.top_items) {
      double lb2, ub2;
      std::int32_t site;
      item_bounds(x, top, pieces.data(), groups.data(), &lb2, &ub2, &site);
      if (lb2 > threshold) continue;
      const std::int32_t count = refine_kept(x, top, pieces.data(), groups.data(), radius, threshold, nullptr);
      std::vector<std::int32_t> out(static_cast<std::size_t>(count) + 1, 12345);
      ASSERT_EQ(refine_kept(x, top, pieces.data(), groups.data(), radius, threshold, out.data()), count);
      ASSERT_EQ(out[static_cast<std::size_t>(count)], 12345) << "written past the count";
      out.pop_back();
      if (is_group_item(top) && splits_item(groups.data(), top, radius)) ++refined;
      if (count == 0) ++dropped;
      // The pieces each listed item stands for, in order.
      std::vector<std::int32_t> covered;
      for (const std::int32_t item : out) {
        if (!is_group_item(item)) {
          EXPECT_LE(piece_chord2(x, pieces[item]), threshold);
          covered.push_back(item);
          continue;
        }
        const PieceGroup& g = groups[item_group(item)];
        item_bounds(x, item, pieces.data(), groups.data(), &lb2, &ub2, &site);
        EXPECT_LE(lb2, threshold);
        if (item != top) {
          EXPECT_FALSE(splits_item(groups.data(), item, radius));
        }
        for (std::int32_t p = g.first; p < g.first + g.count; ++p) covered.push_back(p);
      }
      EXPECT_TRUE(std::is_sorted(covered.begin(), covered.end())) << "not in preorder";
      const std::int32_t first = is_group_item(top) ? groups[item_group(top)].first : top;
      const std::int32_t last = is_group_item(top) ? first + groups[item_group(top)].count : top + 1;
      for (std::int32_t p = first; p < last; ++p) {
        if (piece_chord2(x, pieces[p]) <= threshold) {
          EXPECT_TRUE(std::binary_search(covered.begin(), covered.end(), p)) << "piece " << p << " lost";
        }
      }
    }
  }
  EXPECT_GT(refined, 50u);  // loose groups were refined
  EXPECT_GT(dropped, 5u);   // and some were dropped whole
}

}  // namespace
}  // namespace qtmv::label
