// work_ahead: every block begun on one helper thread, its pieces made once each (by the helper's
// team, or by the writing thread while it waits), written here in order, at most two blocks held
// at once; an exception from a block's start, a piece or the writer comes out, after the helper
// has stopped.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "common/openmp_threads.hpp"
#include "write/work_ahead.hpp"

namespace qtmv::write {
namespace {

/// Counts the blocks alive.
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

/// A block's results: each piece's count of makings, and who made it.
struct Block {
  std::size_t first = 0, last = 0;
  std::vector<std::atomic<int>> made;
  std::vector<std::thread::id> by;
  std::shared_ptr<int> alive;
};

TEST(WorkAhead, EveryPieceOnceEveryBlockInOrderTwoHeldAtMost) {
  for (int threads : {1, 2, 4}) {
    const ScopedDefaultThreads team(threads);
    for (std::size_t count : {0u, 1u, 9u, 10u, 11u, 1000u}) {
      SCOPED_TRACE(std::to_string(count) + " items, " + std::to_string(threads) + " threads");
      Counter blocks;
      std::set<std::thread::id> beginners;
      std::set<std::thread::id> makers;
      std::mutex makers_lock;
      std::vector<std::pair<std::size_t, std::size_t>> written;
      const auto begin = [&](std::size_t first, std::size_t last) {
        beginners.insert(std::this_thread::get_id());  // only the helper begins
        auto block = std::make_unique<Block>();
        block->first = first;
        block->last = last;
        block->made = std::vector<std::atomic<int>>(last - first);
        block->by.resize(last - first);
        block->alive = blocks.hold();
        return std::make_pair(std::move(block), last - first);
      };
      const auto item = [&](std::unique_ptr<Block>& block, std::size_t k) {
        ++block->made[k];
        block->by[k] = std::this_thread::get_id();
        if (k % 3 == 0) std::this_thread::sleep_for(std::chrono::microseconds(50));  // uneven pieces
      };
      const auto write = [&](std::size_t first, std::size_t last, std::unique_ptr<Block>& block) {
        EXPECT_EQ(block->first, first);
        EXPECT_EQ(block->last, last);
        for (std::size_t k = 0; k < block->made.size(); ++k) EXPECT_EQ(block->made[k].load(), 1) << first + k;
        const std::lock_guard<std::mutex> lock(makers_lock);
        makers.insert(block->by.begin(), block->by.end());
        written.emplace_back(first, last);
        std::this_thread::sleep_for(std::chrono::microseconds(count % 2 ? 0 : 200));  // a slow writer, or none
      };
      work_ahead(count, 10, 2, begin, item, write);
      std::size_t at = 0;
      for (const auto& [first, last] : written) {
        EXPECT_EQ(first, at);
        EXPECT_EQ(last, std::min(count, first + 10));
        at = last;
      }
      EXPECT_EQ(at, count);
      EXPECT_LE(beginners.size(), 1u);
      EXPECT_EQ(beginners.count(std::this_thread::get_id()), 0u);
      EXPECT_LE(blocks.most.load(), 2);
      EXPECT_EQ(blocks.alive.load(), 0);
    }
  }
}

TEST(WorkAhead, TheWriterHelpsWhenItWaits) {
  // One thread: the helper's team is the helper alone, and slow pieces leave the writer waiting,
  // so it makes some of them.
  const ScopedDefaultThreads one(1);
  std::set<std::thread::id> makers;
  std::mutex lock;
  const auto begin = [](std::size_t first, std::size_t last) { return std::make_pair(first, last - first); };
  const auto item = [&](std::size_t&, std::size_t) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    const std::lock_guard<std::mutex> hold(lock);
    makers.insert(std::this_thread::get_id());
  };
  const auto write = [](std::size_t, std::size_t, std::size_t&) {};
  work_ahead(400, 100, 1, begin, item, write);
  EXPECT_EQ(makers.count(std::this_thread::get_id()), 1u);
  EXPECT_EQ(makers.size(), 2u);
}

TEST(WorkAhead, ABlocksStartOrPieceThrowingComesOut) {
  for (bool in_piece : {false, true}) {
    SCOPED_TRACE(in_piece ? "a piece" : "a block's start");
    std::size_t written = 0;
    const auto begin = [&](std::size_t first, std::size_t last) {
      if (!in_piece && first == 30) throw std::runtime_error("block 30");
      return std::make_pair(first, last - first);
    };
    const auto item = [&](std::size_t& first, std::size_t k) {
      if (in_piece && first + k == 35) throw std::runtime_error("block 30");
    };
    const auto write = [&](std::size_t first, std::size_t last, std::size_t&) { written += last - first; };
    try {
      work_ahead(100, 10, 3, begin, item, write);
      ADD_FAILURE() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "block 30");
    }
    EXPECT_EQ(written, 30u);
  }
}

TEST(WorkAhead, TheWritersExceptionStopsTheHelper) {
  std::atomic<std::size_t> begun{0};
  const auto begin = [&](std::size_t first, std::size_t last) {
    ++begun;
    return std::make_pair(first, last - first);
  };
  const auto item = [](std::size_t&, std::size_t) {};
  const auto write = [&](std::size_t first, std::size_t, std::size_t&) {
    if (first == 20) throw std::logic_error("write 20");
  };
  EXPECT_THROW(work_ahead(1000, 10, 4, begin, item, write), std::logic_error);
  // Blocks 0, 10, 20 and at most the one after: no work beyond once the writer has failed.
  EXPECT_LE(begun.load(), 4u);
}

}  // namespace
}  // namespace qtmv::write
