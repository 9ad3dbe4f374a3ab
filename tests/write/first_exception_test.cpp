// FirstException: an exception thrown inside an OpenMP loop comes out after it, the first one
// only, instead of terminating the process.
#include <gtest/gtest.h>

#include <atomic>
#include <new>
#include <stdexcept>
#include <string>

#include "common/first_exception.hpp"

namespace qtmv::write {
namespace {

TEST(FirstException, ComesOutOfAnOpenMpLoop) {
  FirstException failure;
  std::atomic<int> ran{0};
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < 1000; ++k) {
    failure.run([&] {
      ++ran;
      if (k == 10) throw std::bad_alloc();
      if (k > 10 && k % 100 == 0) throw std::runtime_error("later " + std::to_string(k));
    });
  }
  EXPECT_GT(ran.load(), 10);
  try {
    failure.rethrow();
    FAIL() << "nothing rethrown";
  } catch (const std::bad_alloc&) {
    // the first failure, in order of iterations when one thread runs them
  } catch (const std::runtime_error& e) {
    // with several threads a later iteration may fail first; still one exception, not two
    EXPECT_EQ(std::string(e.what()).rfind("later ", 0), 0u) << e.what();
  }
}

TEST(FirstException, NothingToRethrowWhenAllWent) {
  FirstException failure;
  int sum = 0;
  for (int k = 0; k < 10; ++k) failure.run([&] { sum += k; });
  EXPECT_EQ(sum, 45);
  EXPECT_NO_THROW(failure.rethrow());
}

}  // namespace
}  // namespace qtmv::write
