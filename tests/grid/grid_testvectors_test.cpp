// The grid against ../shared/testvectors (copied to testdata/testvectors): values computed
// from QTM-SPEC.md independently of this project.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "grid/qtm.hpp"

namespace qtmv::grid {
namespace {

constexpr double kDegreeTolerance = 1e-9;  // (degrees)

std::vector<std::vector<std::string>> read_csv(const std::string& name) {
  const std::string path = std::string(QTMV_TESTDATA_DIR) + "/testvectors/" + name;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  std::vector<std::vector<std::string>> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) fields.push_back(field);
    rows.push_back(fields);
  }
  return rows;
}

TEST(GridTestVectors, CellsMatchSpec) {
  const auto rows = read_csv("cells.csv");
  ASSERT_GT(rows.size(), 1000u);
  for (const auto& r : rows) {
    ASSERT_EQ(r.size(), 16u);
    const int level = std::stoi(r[0]);
    const Code code = std::stoull(r[1]);
    SCOPED_TRACE("level " + r[0] + " code " + r[1]);
    const Cell cell = cell_of(code, level);
    EXPECT_EQ(cell.octant, std::stoi(r[2]));
    EXPECT_EQ(cell.row, std::stoul(r[3]));
    EXPECT_EQ(cell.col, std::stoul(r[4]));
    EXPECT_EQ(code_of(cell, level), code);

    const LonLat centre = cell_centre(cell, level);
    EXPECT_NEAR(centre.lon, std::stod(r[5]), kDegreeTolerance);
    EXPECT_NEAR(centre.lat, std::stod(r[6]), kDegreeTolerance);

    Code nb[3];
    neighbours(code, level, nb);
    EXPECT_EQ(nb[kNeighbourLeft], std::stoull(r[7]));
    EXPECT_EQ(nb[kNeighbourRight], std::stoull(r[8]));
    EXPECT_EQ(nb[kNeighbourVertical], std::stoull(r[9]));

    LonLat v[3];
    cell_vertices(cell, level, v);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(v[k].lon, std::stod(r[10 + 2 * k]), kDegreeTolerance) << "vertex " << k;
      EXPECT_NEAR(v[k].lat, std::stod(r[11 + 2 * k]), kDegreeTolerance) << "vertex " << k;
    }
  }
}

TEST(GridTestVectors, PointsLocateToSpecCodes) {
  const auto rows = read_csv("points.csv");
  ASSERT_GT(rows.size(), 1000u);
  for (const auto& r : rows) {
    ASSERT_EQ(r.size(), 4u);
    EXPECT_EQ(lonlat_to_code(std::stod(r[1]), std::stod(r[2]), std::stoi(r[0])), std::stoull(r[3]))
        << "level " << r[0] << " lon " << r[1] << " lat " << r[2];
  }
}

TEST(GridTestVectors, PaperExampleNeighbours) {
  // The seed paper: at level 2, cell 6 has neighbours 5, 7 and 12.
  Code nb[3];
  neighbours(6, 2, nb);
  EXPECT_EQ(nb[0], 5u);
  EXPECT_EQ(nb[1], 7u);
  EXPECT_EQ(nb[2], 12u);
}

}  // namespace
}  // namespace qtmv::grid
