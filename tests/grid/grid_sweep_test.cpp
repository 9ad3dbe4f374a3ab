// Exhaustive sweeps of the grid's invariants at levels 0 to 8, random sweeps at 9 to 24.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>

#include "grid/qtm.hpp"
#include "grid/qtm_checks.hpp"
#include "grid_cell_checks.hpp"

namespace qtmv::grid {
namespace {

using test::check_cell;

constexpr int kExhaustiveMaxLevel = 8;
constexpr int kRandomCodesPerLevel = 20000;
constexpr int kRandomPointsPerLevel = 20000;

TEST(GridSweep, ExhaustiveLevels0To8) {
  for (int level = 0; level <= kExhaustiveMaxLevel; ++level) {
    std::uint64_t failures = 0;
    Code first_failure = kInvalidCode;
    unsigned first_bits = 0;
    for (Code code = 0; code < cell_count(level); ++code) {
      const unsigned bits = check_cell(code, level);
      if (bits != 0 && failures++ == 0) {
        first_failure = code;
        first_bits = bits;
      }
    }
    EXPECT_EQ(failures, 0u) << "level " << level << ", first failing code " << first_failure << " (failure bits "
                            << first_bits << ")";
  }
}

TEST(GridSweep, CentreVectorsEqualCellCentreVectorBitForBit) {
  // In code order (rows, as the CPU's passes walk them), then in random order (no latitude
  // kept), at every level to the exhaustive limit and a sample of finer ones.
  const auto same = [](const Vec3& a, const Vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; };
  std::mt19937_64 rng(5);
  for (int level = 0; level <= 12; ++level) {
    CentreVectors centres;
    std::uint64_t differ = 0;
    const Code step = level <= kExhaustiveMaxLevel ? 1 : cell_count(level) / 500000 + 1;
    Cell c = cell_of(0, level);
    for (Code code = 0; code < cell_count(level); code += step) {
      if (step > 1) c = cell_of(code, level);
      differ += !same(centres(c, level), cell_centre_vector(c, level));
      if (step == 1) next_in_code_order(c, level);
    }
    std::uniform_int_distribution<Code> any(0, cell_count(level) - 1);
    for (int k = 0; k < 20000; ++k) {
      const Code code = any(rng);
      differ += !same(centres(code, level), cell_centre_vector(code, level));
    }
    // Children of random parents, four at a time, as the tree's passes meet them (three
    // latitudes each, some kept from the parent before).
    if (level > 0) {
      std::uniform_int_distribution<Code> parent(0, cell_count(level - 1) - 1);
      for (int k = 0; k < 5000; ++k) {
        Cell kids[4];
        children(cell_of(parent(rng), level - 1), kids);
        for (const Cell& kid : kids) differ += !same(centres(kid, level), cell_centre_vector(kid, level));
      }
    }
    EXPECT_EQ(differ, 0u) << "level " << level;
  }
}

TEST(GridSweep, CellCountsAndCodeLayout) {
  for (int level = 0; level <= kMaxLevel; ++level) {
    EXPECT_EQ(cell_count(level), 8 * cells_per_octant(level));
    const std::uint64_t last_row = rows_per_octant(level) - 1;
    // The last cell of each octant is the last cell of its last row.
    for (int octant = 0; octant < kOctants; ++octant) {
      const Code last = code_of({octant, static_cast<std::uint32_t>(last_row), static_cast<std::uint32_t>(2 * last_row)},
                                level);
      EXPECT_EQ(last + 1, (octant + 1) * cells_per_octant(level));
    }
  }
  EXPECT_GT(cell_count(15), std::uint64_t{1} << 32);  // codes need 64 bits from level 15
}

TEST(GridSweep, EveryCodeOfOneOctantRowIsItsRow) {
  // Rows partition the codes: row i holds 2i + 1 consecutive codes starting at i^2.
  const int level = 6;
  Code expected = 0;
  for (std::uint32_t i = 0; i < rows_per_octant(level); ++i) {
    for (std::uint32_t j = 0; j <= 2 * i; ++j) {
      const Cell c = cell_of(expected, level);
      ASSERT_EQ(c.octant, 0);
      ASSERT_EQ(c.row, i);
      ASSERT_EQ(c.col, j);
      ++expected;
    }
  }
}

TEST(GridSweep, RandomCodesLevels9To24) {
  std::mt19937_64 rng(20261121);
  for (int level = kExhaustiveMaxLevel + 1; level <= kMaxLevel; ++level) {
    std::uniform_int_distribution<Code> pick(0, cell_count(level) - 1);
    int failures = 0;
    for (int n = 0; n < kRandomCodesPerLevel; ++n) {
      const Code code = pick(rng);
      const unsigned bits = check_cell(code, level);
      if (bits != 0 && failures++ < 5) ADD_FAILURE() << "level " << level << " code " << code << " bits " << bits;
    }
    // The extreme codes of each level, where row and column arithmetic is most likely to overflow.
    EXPECT_EQ(check_cell(0, level), 0u) << "level " << level;
    EXPECT_EQ(check_cell(cell_count(level) - 1, level), 0u) << "level " << level;
    EXPECT_EQ(failures, 0) << "level " << level;
  }
}

TEST(GridSweep, RandomPointsNestAcrossLevels) {
  // The planar subdivision nests, and the location arithmetic is exact at the points where it
  // matters (scaling by 2 and subtracting a floor), so a point's cell at level L has the
  // point's cell at L-1 as its parent.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> lon(-180.0, 180.0), z(-1.0, 1.0);
  for (int n = 0; n < kRandomPointsPerLevel; ++n) {
    const double p_lon = lon(rng), p_lat = std::asin(z(rng)) / kDegree;
    Code coarser = lonlat_to_code(p_lon, p_lat, 0);
    for (int level = 1; level <= kMaxLevel; ++level) {
      const Code code = lonlat_to_code(p_lon, p_lat, level);
      ASSERT_TRUE(is_valid_code(code, level));
      ASSERT_EQ(parent(code, level), coarser) << "lon " << p_lon << " lat " << p_lat << " level " << level;
      coarser = code;
    }
  }
}

TEST(GridSweep, PointsOnEdgesAndSpecialPlaces) {
  // Octant edges, poles, the equator and +-180 at every level: a valid code, in the octant
  // the spec's table gives.
  struct Place {
    double lon, lat;
    int octant;
  };
  const Place places[] = {{0, 90, 0},     {0, -90, 4},   {180, 0, 2},  {-180, 0, 2},  {90, 0, 1},
                          {-90, 0, 3},    {0, 0, 0},     {0, -1e-300, 4}, {-0.0, 0, 0}, {179.9999999999, 45, 1},
                          {-180, -45, 6}, {89.999999, -0.0, 0}, {45, -89.999999999, 4}};
  for (int level = 0; level <= kMaxLevel; ++level) {
    for (const Place& p : places) {
      const Code code = lonlat_to_code(p.lon, p.lat, level);
      ASSERT_TRUE(is_valid_code(code, level)) << p.lon << " " << p.lat;
      EXPECT_EQ(cell_of(code, level).octant, p.octant) << p.lon << " " << p.lat << " level " << level;
    }
  }
}

TEST(GridSweep, PointsOnGridVerticesGoToTheUpCell) {
  // On a vertex fw = fv = 0, and the spec's "up when fw <= fv" decides. Dyadic coordinates keep
  // v and w exact, so these points really lie on vertices.
  const double locals[] = {22.5, 45.0, 67.5};  // w is then a multiple of 1/16: a vertex from level 4
  for (int level = 4; level <= 12; ++level) {
    const double rows = static_cast<double>(rows_per_octant(level));
    for (double lon_local : locals) {
      for (double lat_local : locals) {
        const double v = (90.0 - lat_local) / 90.0, w = lon_local / 90.0 * v;
        const Cell expected{0, static_cast<std::uint32_t>(v * rows), static_cast<std::uint32_t>(2 * w * rows)};
        ASSERT_TRUE(is_up(expected));
        EXPECT_EQ(lonlat_to_code(lon_local, lat_local, level), code_of(expected, level))
            << lon_local << " " << lat_local << " level " << level;
      }
    }
  }
}

TEST(GridSweep, LongitudesAreNormalisedExactly) {
  const int level = 12;
  EXPECT_EQ(lonlat_to_code(540.0, 10.0, level), lonlat_to_code(180.0, 10.0, level));
  EXPECT_EQ(lonlat_to_code(-190.25, 10.0, level), lonlat_to_code(169.75, 10.0, level));
  EXPECT_EQ(lonlat_to_code(720.5, -33.0, level), lonlat_to_code(0.5, -33.0, level));
  EXPECT_EQ(normalise_lon(180.0), -180.0);
  EXPECT_EQ(normalise_lon(12.3456789), 12.3456789);  // in range: untouched, bit for bit
}

TEST(GridSweep, BadInputGivesInvalidCode) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(lonlat_to_code(nan, 0, 5), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(0, nan, 5), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(inf, 0, 5), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(0, 90.0000001, 5), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(0, -95, 5), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(0, 0, -1), kInvalidCode);
  EXPECT_EQ(lonlat_to_code(0, 0, 25), kInvalidCode);
  EXPECT_FALSE(is_valid_code(cell_count(3), 3));
  EXPECT_FALSE(is_valid_level(25));
}

TEST(GridSweep, HostChecksNameTheBadValue) {
  EXPECT_NO_THROW(require_level(0));
  EXPECT_NO_THROW(require_level(24));
  try {
    require_level(25);
    FAIL() << "level 25 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("25"), std::string::npos) << e.what();
  }
  EXPECT_THROW(require_level(-1), std::invalid_argument);
  try {
    require_code(512, 2);
    FAIL() << "code 512 accepted at level 2";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("512"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0 to 127"), std::string::npos) << e.what();
  }
}

TEST(GridSweep, PolygonsAreCounterClockwiseAndPoleCellsAreQuadrilaterals) {
  for (int level = 0; level <= 5; ++level) {
    for (Code code = 0; code < cell_count(level); ++code) {
      const Cell cell = cell_of(code, level);
      LonLat ring[kMaxPolygonCorners];
      const int n = cell_polygon(cell, level, ring);
      ASSERT_EQ(n, cell.row == 0 ? 4 : 3);
      double twice_area = 0;  // shoelace, in lon/lat
      for (int k = 0; k < n; ++k) {
        const LonLat& p = ring[k];
        const LonLat& q = ring[(k + 1) % n];
        twice_area += p.lon * q.lat - q.lon * p.lat;
      }
      EXPECT_GT(twice_area, 0) << "level " << level << " code " << code;
      if (n == 4) {
        EXPECT_EQ(std::fabs(ring[0].lat), 90.0);
        EXPECT_EQ(std::fabs(ring[3].lat), 90.0);
      }
      // The ring stays inside one octant's longitudes: nothing crosses +-180.
      for (int k = 0; k < n; ++k) {
        EXPECT_LE(std::fabs(ring[k].lon - ring[(k + 1) % n].lon), 90.0);
      }
    }
  }
}

TEST(GridSweep, PolygonCornersHaveTheSameKeyExactlyWhereTheyAreTheSamePoint) {
  // Every corner of every cell of levels 0 to 8 (random cells at 12 and 24): a key names one point
  // (its bits; -0 is 0), and a point one key, across octants' sides, the equator and the poles'
  // lines; +-180 are two points. The corners' key layout holds: the column is the longitude's.
  std::mt19937_64 rng(5);
  for (int level : {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 24}) {
    std::map<std::uint64_t, std::pair<double, double>> point_of_key;
    std::map<std::pair<double, double>, std::uint64_t> key_of_point;
    std::uint64_t wrong = 0;
    const auto visit = [&](Code code) {
      const Cell cell = cell_of(code, level);
      LonLat ring[kMaxPolygonCorners];
      std::uint64_t keys[kMaxPolygonCorners];
      const int n = cell_polygon(cell, level, ring);
      ASSERT_EQ(cell_polygon_keys(cell, level, keys), n);
      for (int k = 0; k < n; ++k) {
        const std::pair<double, double> point{ring[k].lon + 0.0, ring[k].lat + 0.0};
        const auto [at_key, new_key] = point_of_key.emplace(keys[k], point);
        const auto [at_point, new_point] = key_of_point.emplace(point, keys[k]);
        wrong += at_key->second != point || at_point->second != keys[k];
        const std::uint64_t tag = keys[k] >> kVertexKeyTagShift;
        const std::uint64_t r = keys[k] >> kVertexKeyRowShift & ((std::uint64_t{1} << (kVertexKeyTagShift - kVertexKeyRowShift)) - 1);
        const std::uint64_t g = keys[k] & ((std::uint64_t{1} << kVertexKeyRowShift) - 1);
        if (tag == kVertexKeyPoleLine) {
          wrong += std::fabs(point.second) != 90.0 || point.first != 90.0 * static_cast<double>(g) - 180.0;
        } else {
          wrong += std::fabs(90.0 * static_cast<double>(g) / static_cast<double>(r) - 180.0 - point.first) > 1e-9;
        }
      }
    };
    if (level <= kExhaustiveMaxLevel) {
      for (Code code = 0; code < cell_count(level); ++code) visit(code);
      // Each vertex once: (r + 1) per row line of each octant, shared sides, equator and poles'
      // lines counted once, the two points at +-180 on each row line kept apart.
      const std::uint64_t rows = rows_per_octant(level);
      std::uint64_t expected = 2 * 5;  // the poles' lines: -180, -90, 0, 90, 180
      for (std::uint64_t r = 1; r < rows; ++r) expected += 2 * (4 * r + 1);
      expected += 4 * rows + 1;  // the equator
      EXPECT_EQ(point_of_key.size(), expected) << "level " << level;
    } else {
      std::uniform_int_distribution<Code> any(0, cell_count(level) - 1);
      for (int n = 0; n < kRandomCodesPerLevel; ++n) {
        const Code code = any(rng);
        visit(code);
        Code nb[3];
        neighbours(code, level, nb);
        for (const Code c : nb) visit(c);
      }
    }
    EXPECT_EQ(wrong, 0u) << "level " << level;
  }
}

}  // namespace
}  // namespace qtmv::grid
