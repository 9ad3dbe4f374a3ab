// Helpers for the tests of partitioned output (vector and raster parts): tile jobs writing parts,
// the parts' index, and an index expected refused.
#pragma once

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "voronoi.hpp"

namespace qtmv::test {

/// Tile jobs k = 1..n of `source` (those of `which`, all when empty) writing parts
/// dir/k.`extension`.
inline void run_parts(const std::string& source, VoronoiOptions options, int n, const std::string& dir,
                      const std::string& extension, const std::vector<int>& which = {}) {
  std::filesystem::create_directories(dir);
  options.part = true;
  options.tile_count = n;
  for (int k = 1; k <= n; ++k) {
    if (!which.empty() && std::find(which.begin(), which.end(), k) == which.end()) continue;
    options.tile_index = k;
    run_voronoi(source, dir + "/" + std::to_string(k) + "." + extension, options);
  }
}

/// The index of `parts` (-merge PARTS -of VRT) written at `index`.
inline VoronoiSummary run_index(const std::vector<std::string>& parts, const std::string& index) {
  VoronoiOptions options;
  options.merge = parts;
  options.format = "VRT";
  return run_voronoi("", index, options);
}

/// Runs the index of `parts` and expects it refused with every one of `says` in its message,
/// leaving nothing at `index`.
inline void expect_index_refused(const std::vector<std::string>& parts, const std::vector<std::string>& says,
                                 const std::string& index) {
  try {
    run_index(parts, index);
    ADD_FAILURE() << "accepted: " << says.front();
  } catch (const VoronoiError& e) {
    for (const std::string& s : says) EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(index));
}

}  // namespace qtmv::test
