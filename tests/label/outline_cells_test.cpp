// The outline cells' packing (label::OutlineCell in 12 bytes), the CPU pass's join of its
// threads' lists (outline_join.hpp) against one sort of them all, and the cells per site counted
// on any number of threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "common/openmp_threads.hpp"
#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"
#include "label/outline_join.hpp"

namespace qtmv::label {
namespace {

TEST(OutlineCell, PacksEveryCodeOfTheFinestLevelWithItsFlagAndSite) {
  static_assert(sizeof(OutlineCell) == 12, "12 bytes");
  const grid::Code last = grid::cell_count(grid::kMaxLevel) - 1;
  for (const grid::Code code : {grid::Code{0}, grid::Code{1} << 31, grid::Code{0xffffffff}, grid::Code{1} << 32, last}) {
    for (const unsigned flag : {0u, 1u}) {
      const OutlineCell c(code, 2147483647, flag);
      EXPECT_EQ(c.code(), code);
      EXPECT_EQ(c.boundary(), flag != 0);
      EXPECT_EQ(c.site, 2147483647);
      OutlineCell marked = c;
      marked.mark_boundary();
      EXPECT_EQ(marked.code(), code);
      EXPECT_TRUE(marked.boundary());
    }
  }
}

// The reference: every list concatenated in order, sorted stably by code, each code once (the
// first listing's site, a boundary cell if any listing says so), those of the range.
OutlineCells one_sort(const std::vector<OutlineCells>& parts, grid::CodeRange range) {
  OutlineCells all;
  for (const OutlineCells& p : parts) all.insert(all.end(), p.begin(), p.end());
  std::stable_sort(all.begin(), all.end(), [](const OutlineCell& a, const OutlineCell& b) { return a.code() < b.code(); });
  OutlineCells out;
  for (const OutlineCell& c : all) {
    if (c.code() < range.first || c.code() >= range.end) continue;
    if (!out.empty() && out.back().code() == c.code()) {
      if (c.boundary()) out.back().mark_boundary();
    } else {
      out.push_back(c);
    }
  }
  return out;
}

TEST(OutlineJoin, EqualsOneSortOfAllListsWhateverTheThreads) {
  const int level = 7;
  std::mt19937_64 random(37);
  for (const int lists : {1, 2, 3, 8}) {
    std::vector<OutlineCells> parts(static_cast<std::size_t>(lists));
    // Codes listed by several lists and more than once in one, with sites that tell the
    // listings apart (the first listing's must win).
    for (int k = 0; k < 20000; ++k) {
      const grid::Code code = random() % grid::cell_count(level);
      const int copies = 1 + static_cast<int>(random() % 3);
      for (int c = 0; c < copies; ++c) {
        parts[random() % parts.size()].push_back(
            {code, static_cast<std::int32_t>(random() % 1000), static_cast<unsigned>(random() % 4 == 0)});
      }
    }
    const grid::CodeRange whole = grid::whole_level(level);
    const grid::CodeRange part{grid::cell_count(level) / 3, grid::cell_count(level) / 3 * 2};
    for (const grid::CodeRange range : {whole, part}) {
      const OutlineCells want = one_sort(parts, range);
      for (const int threads : {1, 2, 5}) {
        std::vector<OutlineCells> copy = parts;
        const OutlineCells got = join_outline_parts(copy, level, range, threads);
        ASSERT_EQ(got.size(), want.size()) << lists << " lists, " << threads << " threads";
        for (std::size_t k = 0; k < got.size(); ++k) {
          ASSERT_TRUE(got[k].code() == want[k].code() && got[k].site == want[k].site &&
                      got[k].boundary() == want[k].boundary())
              << "cell " << k << " of " << lists << " lists, " << threads << " threads";
        }
        for (const OutlineCells& p : copy) EXPECT_EQ(p.capacity(), 0u);  // freed
      }
    }
  }
}

TEST(OutlineCells, CellsPerSiteWhateverTheThreads) {
  // Runs of one site (added at once by each thread) of every length, some across the threads'
  // shares, a site's runs far apart; and a range that ends before the level does.
  const int level = 6;
  std::mt19937_64 random(37);
  OutlineCells cells;
  std::int32_t site = 0;
  for (grid::Code code = 0; code < grid::cell_count(level); code += 1 + random() % 5) {
    if (random() % 3 == 0) site = static_cast<std::int32_t>(random() % 50);
    cells.push_back({code, site, 1});
  }
  for (const grid::Code end : {grid::Code{0}, cells.back().code() + 3}) {
    std::vector<std::uint64_t> want(50, 0);
    const grid::Code last = end == 0 ? grid::cell_count(level) : end;
    for (std::size_t k = 0; k < cells.size(); ++k) {
      want[static_cast<std::size_t>(cells[k].site)] += (k + 1 < cells.size() ? cells[k + 1].code() : last) - cells[k].code();
    }
    for (const int threads : {1, 2, 3, 8}) {
      const ScopedDefaultThreads scoped(threads);
      EXPECT_EQ(count_cells_per_site(cells, level, 50, end), want) << threads << " threads, end " << end;
    }
  }
}

}  // namespace
}  // namespace qtmv::label
