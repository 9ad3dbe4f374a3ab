// The host tree build's guard (tree_build.cpp, check_level_fits): a level whose candidate lists
// could not fit in half the memory the host can give is refused with a message saying why,
// before it is filtered, rather than the kernel ending the process. The host is made small by
// the fault switch QTMV_FAULT_AVAILABLE_MEMORY (bytes).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "grid/qtm.hpp"
#include "label/label_engine.hpp"

namespace qtmv::label {
namespace {

/// `count` short lines (about 50 m), each its own site, in a box of 0.02 degrees, and 3 points
/// far away: every node far from the box keeps most of the lines (the bisector rule prunes
/// points only). With `spread`, the lines' starts spread over the globe instead.
std::vector<Piece> short_lines(int count, bool spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> box(0.0, 0.02), lon(-180.0, 179.0), z(-0.99, 0.99);
  std::vector<Piece> pieces;
  for (int k = 0; k < count; ++k) {
    const double x = spread ? lon(rng) : 10.0 + box(rng);
    const double y = spread ? std::asin(z(rng)) * 180.0 / grid::kPi : 45.0 + box(rng);
    pieces.push_back(make_arc_piece(grid::unit_vector(x, y), grid::unit_vector(x + 0.0005, y + 0.0003), k));
  }
  const double far[3][2] = {{-120.0, 30.0}, {100.0, -40.0}, {0.0, -80.0}};
  for (const auto& f : far) {
    pieces.push_back(make_point_piece(grid::unit_vector(f[0], f[1]), static_cast<std::int32_t>(pieces.size())));
  }
  return pieces;
}

/// Sets the fault switch for the scope.
struct SmallHost {
  explicit SmallHost(std::uint64_t bytes) { ::setenv("QTMV_FAULT_AVAILABLE_MEMORY", std::to_string(bytes).c_str(), 1); }
  ~SmallHost() { ::unsetenv("QTMV_FAULT_AVAILABLE_MEMORY"); }
  SmallHost(const SmallHost&) = delete;
  SmallHost& operator=(const SmallHost&) = delete;
};

constexpr int kLevel = 7;
constexpr std::uint64_t kSmallHost = std::uint64_t{64} << 20;

TEST(TreeGuard, RefusesALevelWhoseListsCannotFit) {
  const std::vector<Piece> cluster = short_lines(300, false, 7);
  // On this host the tree is built (level 7's lists: about 10 million entries, 43 MB).
  const Tree whole = build_tree(cluster, kLevel, false, 2);
  EXPECT_GT(whole.nodes.size(), std::size_t{8});
  // On a host with 64 MiB to give, the build stops before level 7 and says why.
  const SmallHost small(kSmallHost);
  try {
    (void)build_tree(cluster, kLevel, false, 2);
    ADD_FAILURE() << "the tree of a cluster of lines was built on a host of 64 MiB";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("at level 7 of 7"), std::string::npos) << message;
    EXPECT_NE(message.find("tight clusters"), std::string::npos) << message;
    EXPECT_NE(message.find("choose a lower -level"), std::string::npos) << message;
  }
}

TEST(TreeGuard, LetsSpreadSitesThroughOnTheSameHost) {
  // The same lines spread over the globe: short lists, built on the small host as on this one,
  // node for node.
  const std::vector<Piece> spread = short_lines(300, true, 7);
  const Tree here = build_tree(spread, kLevel, false, 2);
  const SmallHost small(kSmallHost);
  const Tree there = build_tree(spread, kLevel, false, 2);
  ASSERT_EQ(there.nodes.size(), here.nodes.size());
  EXPECT_EQ(there.lists, here.lists);
}

}  // namespace
}  // namespace qtmv::label
