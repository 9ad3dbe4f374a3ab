// work_ahead: every block made on one helper thread and written here, in order, at most two
// blocks held at once; an exception from either side comes out, after the helper has stopped.
#include <gtest/gtest.h>

#include <atomic>
#include <cstddef>
#include <memory>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "write/work_ahead.hpp"

namespace qtmv::write {
namespace {

/// A block's results; counts the blocks alive.
struct Block {
  std::size_t first = 0, last = 0;
  std::shared_ptr<int> alive;
};

struct Counter {
  std::atomic<int> alive{0}, most{0};
  std::shared_ptr<int> hold() {
    const int now = ++alive;
    for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
    }
    return std::shared_ptr<int>(new int(0), [this](int* p) {
      --alive;
      delete p;
    });
  }
};

TEST(WorkAhead, EveryBlockInOrderOnOneHelperThreadTwoHeldAtMost) {
  for (std::size_t count : {0u, 1u, 9u, 10u, 11u, 1000u}) {
    SCOPED_TRACE(count);
    Counter blocks;
    std::set<std::thread::id> helpers;
    std::vector<std::pair<std::size_t, std::size_t>> written;
    const auto work = [&](std::size_t first, std::size_t last) {
      helpers.insert(std::this_thread::get_id());  // only the helper writes it
      return Block{first, last, blocks.hold()};
    };
    const auto write = [&](std::size_t first, std::size_t last, Block& block) {
      EXPECT_EQ(block.first, first);
      EXPECT_EQ(block.last, last);
      written.emplace_back(first, last);
    };
    work_ahead(count, 10, work, write);
    std::size_t at = 0;
    for (const auto& [first, last] : written) {
      EXPECT_EQ(first, at);
      EXPECT_EQ(last, std::min(count, first + 10));
      at = last;
    }
    EXPECT_EQ(at, count);
    EXPECT_LE(helpers.size(), 1u);
    EXPECT_EQ(helpers.count(std::this_thread::get_id()), 0u);
    EXPECT_LE(blocks.most.load(), 2);
    EXPECT_EQ(blocks.alive.load(), 0);
  }
}

TEST(WorkAhead, TheHelpersExceptionComesOut) {
  std::size_t written = 0;
  const auto work = [&](std::size_t first, std::size_t last) {
    if (first == 30) throw std::runtime_error("block 30");
    return last - first;
  };
  const auto write = [&](std::size_t, std::size_t, std::size_t n) { written += n; };
  try {
    work_ahead(100, 10, work, write);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "block 30");
  }
  EXPECT_EQ(written, 30u);
}

TEST(WorkAhead, TheWritersExceptionStopsTheHelper) {
  std::atomic<std::size_t> made{0};
  const auto work = [&](std::size_t first, std::size_t) {
    ++made;
    return first;
  };
  const auto write = [&](std::size_t first, std::size_t, std::size_t) {
    if (first == 20) throw std::logic_error("write 20");
  };
  EXPECT_THROW(work_ahead(1000, 10, work, write), std::logic_error);
  // Blocks 0, 10, 20 and at most the one after: no work beyond once the writer has failed.
  EXPECT_LE(made.load(), 4u);
}

}  // namespace
}  // namespace qtmv::write
