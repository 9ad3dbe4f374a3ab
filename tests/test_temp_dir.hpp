// A temporary directory of the test process's own, removed with all it holds when the process
// exits, so that test runs leave nothing behind in the system's temporary directory.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace qtmv::test {

inline const std::string& process_temp_dir() {
  // Never destroyed: the exit handler below runs after static objects are gone.
  static const std::string* dir = [] {
    auto* d = new std::string(::testing::TempDir() + "qtmv_test_" + std::to_string(getpid()));
    std::filesystem::create_directories(*d);
    return d;
  }();
  static const bool removed_at_exit = std::atexit([] {
    std::error_code ignored;
    std::filesystem::remove_all(*dir, ignored);
  }) == 0;
  (void)removed_at_exit;
  return *dir;
}

}  // namespace qtmv::test
