// Helpers for the tests that run the built qtmvoronoi: a directory per test, the pipeline's
// temporary directories in it, running and signalling the binary, reading outputs back.
#pragma once

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include "../test_temp_dir.hpp"
#include "child_process.hpp"

namespace qtmv::test {

namespace fs = std::filesystem;

/// A fresh directory for the current test (no dot in its name: /vsizip/ would take a test
/// named Zip... for an archive).
inline std::string test_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(process_temp_dir()) / (std::string(info->test_suite_name()) + "_" + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

/// Entries of a directory whose names start with a dot: the pipeline's temporary directories.
inline std::vector<std::string> hidden_entries(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().filename().string().front() == '.') names.push_back(e.path().filename().string());
  }
  return names;
}

/// Runs qtmvoronoi; stdout and stderr go to files (outside the directories the tests inspect).
inline ProcessResult run_qtmvoronoi(const std::vector<std::string>& args, const ChildSetup& setup = {},
                                    double timeout_seconds = kDefaultTimeoutSeconds) {
  return run_process(QTMVORONOI_PATH, args, "", setup, timeout_seconds);
}

inline std::vector<std::string> concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

inline GDALDatasetUniquePtr open_dataset(const std::string& path, unsigned flags) {
  GDALAllRegister();
  return GDALDatasetUniquePtr(GDALDataset::Open(path.c_str(), flags | GDAL_OF_READONLY));
}

/// Waits (up to a minute) until `ready` holds, polling; false when it never did.
template <class Predicate>
bool wait_until(Predicate ready) {
  const auto start = std::chrono::steady_clock::now();
  while (!ready()) {
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(60)) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

/// Whether the writer has created `name` inside one of the pipeline's temporary directories of `dir`.
inline bool writing(const std::string& dir, const std::string& name) {
  for (const std::string& entry : hidden_entries(dir)) {
    std::error_code ec;
    if (fs::exists(fs::path(dir) / entry / name, ec)) return true;
  }
  return false;
}

/// Starts qtmvoronoi with `args`, waits until `ready(path of its stderr)` holds, 300 ms more,
/// then sends it `signal_number` and waits for it to end; `seconds` gets the time from the
/// signal to its exit. A run that never gets ready fails the test.
template <class Ready>
ProcessResult interrupt_when(const std::vector<std::string>& args, Ready ready, int signal_number, double& seconds) {
  static int serial = 0;
  const std::string base = process_temp_dir() + "/interrupted_" + std::to_string(serial++);
  const std::string out = base + ".out", err = base + ".err";
  const pid_t pid = spawn_process(QTMVORONOI_PATH, args, "", out, err);
  if (pid <= 0) {  // never kill(-1, ...): that signals every process of the user
    ADD_FAILURE() << "cannot start " << QTMVORONOI_PATH;
    return {};
  }
  EXPECT_TRUE(wait_until([&] { return ready(err); })) << "never got ready: " << read_file(err);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_EQ(kill(pid, signal_number), 0);
  ProcessResult r = wait_process(pid, out, err);
  seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count();
  return r;
}

/// What an interrupted run must show: status 1, the signal and the destination named, an exit
/// within `limit` seconds of the signal, neither the destination nor a temporary directory.
inline void expect_interrupted(const ProcessResult& r, const std::string& signal_name, const std::string& dst,
                               double seconds, double limit) {
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("qtmvoronoi: interrupted by " + signal_name + ": '" + dst + "' not written"),
            std::string::npos)
      << r.err;
  EXPECT_LT(seconds, limit);
  EXPECT_FALSE(fs::exists(dst));
  EXPECT_TRUE(hidden_entries(fs::path(dst).parent_path().string()).empty());
}

/// Sends `signal_number` (named `signal_name`) to a run that writes every cell of level 9 of
/// `source_args` as a polygon (seconds of writing) once its writer has started: it must stop
/// within `limit` seconds and leave nothing.
inline void expect_clean_stop_while_writing(const std::vector<std::string>& source_args, int signal_number,
                                            const std::string& signal_name, double limit) {
  const std::string dir = test_dir();
  const std::string dst = dir + "/cells.gpkg";
  double seconds = 0;
  const ProcessResult r = interrupt_when(
      concat(concat({"-level", "9", "-device", "cpu", "-layers", "cells"}, source_args), {dst}),
      [&](const std::string&) { return writing(dir, "cells.gpkg"); }, signal_number, seconds);
  expect_interrupted(r, signal_name, dst, seconds, limit);
}

}  // namespace qtmv::test
