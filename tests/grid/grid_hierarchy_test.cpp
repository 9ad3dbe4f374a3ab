// The QTM hierarchy (qtm_hierarchy.hpp) against the grid's own parent, children and neighbours:
// sampled cells of every level, and every cell of the low levels.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "grid/qtm.hpp"

namespace qtmv::grid {
namespace {

TEST(GridHierarchy, AncestorAndChildDigitAgreeWithTheGrid) {
  std::mt19937_64 rng(3);
  for (int level = 0; level <= 24; ++level) {
    std::uniform_int_distribution<Code> pick(0, cell_count(level) - 1);
    for (int trial = 0; trial < 2000; ++trial) {
      const Code code = trial < 8 ? std::min<Code>(trial, cell_count(level) - 1) : pick(rng);
      const Cell c = cell_of(code, level);
      Cell up = c;
      for (int to = level - 1; to >= 0; --to) {
        const Cell child = up;
        up = parent(up);
        const Cell anc = ancestor(c, level, to);
        ASSERT_TRUE(anc.octant == up.octant && anc.row == up.row && anc.col == up.col)
            << code << " level " << level << " to " << to;
        Cell kids[4];
        children(up, kids);
        const int d = child_digit(child);
        ASSERT_TRUE(kids[d].row == child.row && kids[d].col == child.col);
      }
    }
  }
}

// Every cell of levels 0 to 6: the keys are a bijection onto [0, 8 4^level), and each ancestor's
// key is the cell's with its last digits dropped (so a node's cells have consecutive keys).
TEST(GridHierarchy, QuadtreeKeysNumberEachNodesCellsConsecutively) {
  for (int level = 0; level <= 6; ++level) {
    const Code cells = cell_count(level);
    std::vector<bool> seen(cells, false);
    for (Code code = 0; code < cells; ++code) {
      const Cell c = cell_of(code, level);
      const std::uint64_t key = quadtree_key(c, level);
      ASSERT_LT(key, cells) << code;
      ASSERT_FALSE(seen[key]) << "key " << key << " twice, level " << level;
      seen[key] = true;
      for (int to = 0; to < level; ++to) {
        ASSERT_EQ(key >> (2 * (level - to)), quadtree_key(ancestor(c, level, to), to)) << code << " to " << to;
      }
    }
  }
}

TEST(GridHierarchy, DescendantsCoverTheirAncestorOnce) {
  for (int level = 0; level <= 5; ++level) {
    for (int k = 0; k <= 4; ++k) {
      const int below = level + k;
      std::vector<std::uint8_t> seen(cell_count(below), 0);
      for (Code a = 0; a < cell_count(level); ++a) {
        const Cell ac = cell_of(a, level);
        for (std::uint32_t m = 0; m < (1u << (2 * k)); ++m) {
          const Cell d = descendant(ac, k, m);
          ASSERT_LE(d.col, 2 * d.row);
          const Cell back = ancestor(d, below, level);
          ASSERT_EQ(code_of(back, level), a) << "level " << level << " k " << k << " m " << m;
          ++seen[code_of(d, below)];
        }
      }
      EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<std::ptrdiff_t>(seen.size()));
    }
  }
}

TEST(GridHierarchy, InteriorTestMatchesNeighbourAncestors) {
  for (int level = 1; level <= 7; ++level) {
    for (Code code = 0; code < cell_count(level); code += (level > 5 ? 7 : 1)) {
      const Cell c = cell_of(code, level);
      Cell nb[3];
      neighbours(c, level, nb);
      for (int to = 0; to <= level; ++to) {
        const Cell a = ancestor(c, level, to);
        bool all_inside = true;
        for (const Cell& n : nb) {
          const Cell na = ancestor(n, level, to);
          all_inside = all_inside && na.octant == a.octant && na.row == a.row && na.col == a.col;
        }
        ASSERT_EQ(interior_of_ancestor(c, level, to), all_inside) << code << " level " << level << " to " << to;
      }
    }
  }
}

}  // namespace
}  // namespace qtmv::grid
