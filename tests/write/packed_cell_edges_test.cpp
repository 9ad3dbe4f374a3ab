// RegionTracer's packed lists (write/packed_cell_edges.hpp): every code and mask read back as
// written, whole codes where a list (or a thread's part of it) starts, and the sizes promised.
#include "write/packed_cell_edges.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace qtmv::write {
namespace {

using grid::Code;

struct Entry {
  Code code;
  unsigned mask;
  bool whole;  // written as a part's first (after == 0)
};

/// Packs `entries` (codes growing between whole ones) and checks the byte counts on the way.
std::vector<std::uint8_t> pack(const std::vector<Entry>& entries) {
  std::size_t bytes = 0;
  Code counted = 0;
  for (const Entry& e : entries) {
    if (e.whole) counted = 0;
    bytes += packed_cell_edges_bytes(e.code, counted);
  }
  std::vector<std::uint8_t> out(bytes + 1, 0xEE);  // one byte beyond: not to be written
  std::uint8_t* at = out.data();
  Code after = 0;
  for (const Entry& e : entries) {
    if (e.whole) after = 0;
    at = put_packed_cell_edges(at, e.code, e.mask, after);
  }
  EXPECT_EQ(static_cast<std::size_t>(at - out.data()), bytes);
  EXPECT_EQ(out.back(), 0xEE);
  out.pop_back();
  return out;
}

void expect_reads_back(const std::vector<Entry>& entries) {
  const std::vector<std::uint8_t> bytes = pack(entries);
  PackedCellEdgesReader reader(bytes.data(), bytes.data() + bytes.size());
  Code code = 0;
  unsigned mask = 0;
  for (std::size_t k = 0; k < entries.size(); ++k) {
    ASSERT_TRUE(reader.next(code, mask)) << k;
    EXPECT_EQ(code, entries[k].code) << k;
    EXPECT_EQ(mask, entries[k].mask) << k;
  }
  EXPECT_FALSE(reader.next(code, mask));
}

TEST(PackedCellEdges, SmallStepsTakeOneByteAndRowJumpsFew) {
  Code after = 0;
  EXPECT_EQ(packed_cell_edges_bytes(3, after), 1u);    // whole: 3 < 4
  EXPECT_EQ(packed_cell_edges_bytes(7, after), 1u);    // step 3 after 3
  EXPECT_EQ(packed_cell_edges_bytes(8, after), 1u);    // neighbours: step 0
  EXPECT_EQ(packed_cell_edges_bytes(520, after), 2u);  // step 511 < 2^9
  EXPECT_EQ(packed_cell_edges_bytes(520 + 512 + 1, after), 3u);  // step 512
  EXPECT_EQ(after, Code{520 + 512 + 2});
  Code whole = 0;
  EXPECT_EQ(packed_cell_edges_bytes(Code{1} << 43, whole), 7u);  // a level 20 code: 44 bits
  whole = 0;
  EXPECT_EQ(packed_cell_edges_bytes(~Code{0} >> 1, whole), 10u);  // 63 bits: 2 + 7 x 9
}

TEST(PackedCellEdges, EveryEntryReadsBack) {
  expect_reads_back({});
  expect_reads_back({{0, 0, true}});
  expect_reads_back({{0, 15, true}, {1, 1, false}, {2, 2, false}, {1000, 4, false}});
  // A list of two parts (two bucketing threads): the second starts whole again.
  expect_reads_back({{10, 3, true}, {11, 5, false}, {400000, 6, true}, {400002, 9, false}});
  // The largest codes of the finest level and beyond, after small ones.
  const Code top = (Code{8} << (2 * grid::kMaxLevel)) - 1;
  expect_reads_back({{1, 1, true}, {top - 1, 2, false}, {top, 15, false}, {~Code{0} >> 1, 7, true}});
  std::mt19937_64 random(37);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<Entry> entries;
    Code code = 0;
    for (int k = 0; k < 1000; ++k) {
      const bool whole = k == 0 || random() % 97 == 0;
      const int bits = static_cast<int>(random() % 40);  // steps of every size
      code += 1 + (random() & ((Code{1} << bits) - 1));
      entries.push_back({code, static_cast<unsigned>(random() % 16), whole});
    }
    expect_reads_back(entries);
  }
}

}  // namespace
}  // namespace qtmv::write
