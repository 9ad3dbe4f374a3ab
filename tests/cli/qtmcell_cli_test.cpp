// Runs the built qtmcell binary and checks what it prints, its messages and its exit status.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "child_process.hpp"
#include "grid/qtm.hpp"
#include "qtmv_version.hpp"

namespace {

namespace grid = qtmv::grid;

using Result = qtmv::test::ProcessResult;
using qtmv::test::read_file;

std::string read_all(const std::string& path) { return read_file(path); }

// Runs qtmcell with args and stdin.
Result run(const std::vector<std::string>& args, const std::string& input = "") {
  return qtmv::test::run_process(QTMCELL_PATH, args, input);
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream s(text);
  for (std::string line; std::getline(s, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> fields_of(const std::string& line, char sep = ' ') {
  std::vector<std::string> fields;
  std::istringstream s(line);
  for (std::string f; std::getline(s, f, sep);) fields.push_back(f);
  return fields;
}

// A testvectors CSV file as rows of named fields.
std::vector<std::map<std::string, std::string>> read_csv(const std::string& name) {
  std::ifstream f(std::string(QTMV_TESTDATA_DIR) + "/testvectors/" + name);
  std::vector<std::map<std::string, std::string>> rows;
  std::string line;
  if (!std::getline(f, line)) return rows;
  const std::vector<std::string> header = fields_of(line, ',');
  while (std::getline(f, line)) {
    const std::vector<std::string> v = fields_of(line, ',');
    std::map<std::string, std::string> row;
    for (std::size_t k = 0; k < header.size() && k < v.size(); ++k) row[header[k]] = v[k];
    rows.push_back(row);
  }
  return rows;
}

// Rows grouped by level.
std::map<int, std::vector<std::map<std::string, std::string>>> by_level(const std::string& name) {
  std::map<int, std::vector<std::map<std::string, std::string>>> groups;
  for (auto& row : read_csv(name)) groups[std::stoi(row["level"])].push_back(row);
  return groups;
}

// The points of a WKT POLYGON ((x y,x y,...)) as (lon, lat) pairs; empty if it does not parse.
std::vector<grid::LonLat> wkt_ring(const std::string& wkt) {
  static const std::regex shape(R"(^POLYGON \(\(([^()]*)\)\)$)");
  std::smatch m;
  std::vector<grid::LonLat> ring;
  if (!std::regex_match(wkt, m, shape)) return ring;
  for (const std::string& point : fields_of(m[1].str(), ',')) {
    const std::vector<std::string> xy = fields_of(point, ' ');
    if (xy.size() != 2) return {};
    ring.push_back({std::stod(xy[0]), std::stod(xy[1])});
  }
  return ring;
}

std::string level_arg(int level) { return std::to_string(level); }

TEST(QtmcellEncode, TestvectorPointsFromStdinBothForms) {
  for (const auto& [level, rows] : by_level("points.csv")) {
    std::string input;
    std::vector<std::string> expected;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto& row = rows[k];
      // Alternate the two line forms, with some untidy spacing.
      input += k % 3 == 0 ? row.at("lon") + "," + row.at("lat") + "\n"
               : k % 3 == 1 ? row.at("lon") + " " + row.at("lat") + "\n"
                            : "  " + row.at("lon") + " ,\t" + row.at("lat") + " \r\n";
      expected.push_back(row.at("code"));
    }
    const Result r = run({"encode", "-level", level_arg(level)}, input);
    ASSERT_EQ(r.status, 0) << "level " << level << ": " << r.err;
    EXPECT_EQ(r.err, "");
    EXPECT_EQ(lines_of(r.out), expected) << "level " << level;
  }
}

TEST(QtmcellEncode, TestvectorPointsAsArguments) {
  for (const auto& [level, rows] : by_level("points.csv")) {
    std::vector<std::string> args{"encode", "--level", level_arg(level)};
    std::vector<std::string> expected;
    for (std::size_t k = 0; k < rows.size(); k += 7) {  // includes negative longitudes
      args.push_back(rows[k].at("lon"));
      args.push_back(rows[k].at("lat"));
      expected.push_back(rows[k].at("code"));
    }
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(lines_of(r.out), expected) << "level " << level;
  }
  const Result one = run({"encode", "-level", "12", "-122.4194", "37.7749"});
  EXPECT_EQ(one.status, 0);
  EXPECT_EQ(one.out, std::to_string(grid::lonlat_to_code(-122.4194, 37.7749, 12)) + "\n");
}

TEST(QtmcellDecode, TestvectorCells) {
  for (const auto& [level, rows] : by_level("cells.csv")) {
    std::vector<std::string> args{"decode", "-level", level_arg(level)};
    for (const auto& row : rows) args.push_back(row.at("code"));
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.out);
    ASSERT_EQ(lines.size(), rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const std::vector<std::string> f = fields_of(lines[k]);
      ASSERT_EQ(f.size(), 6u) << lines[k];
      EXPECT_EQ(f[0], rows[k].at("code"));
      EXPECT_EQ(f[1], rows[k].at("octant"));
      EXPECT_EQ(f[2], rows[k].at("row"));
      EXPECT_EQ(f[3], rows[k].at("col"));
      EXPECT_NEAR(std::stod(f[4]), std::stod(rows[k].at("centre_lon")), 1e-9) << lines[k];
      EXPECT_NEAR(std::stod(f[5]), std::stod(rows[k].at("centre_lat")), 1e-9) << lines[k];
    }
  }
}

TEST(QtmcellDecode, SeveralCodesPerStdinLine) {
  const Result r = run({"decode", "-level", "2"}, "6 7\n\n# a comment\n\t12   5\n");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].substr(0, 2), "6 ");
  EXPECT_EQ(lines[3].substr(0, 2), "5 ");
}

TEST(QtmcellNeighbours, TestvectorCells) {
  for (const auto& [level, rows] : by_level("cells.csv")) {
    std::string input;
    for (const auto& row : rows) input += row.at("code") + "\n";
    const Result r = run({"neighbours", "-level", level_arg(level)}, input);  // stdin this time
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.out);
    ASSERT_EQ(lines.size(), rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      EXPECT_EQ(lines[k], rows[k].at("nb_left") + " " + rows[k].at("nb_right") + " " + rows[k].at("nb_vertical"));
    }
  }
  // The paper's example.
  EXPECT_EQ(run({"neighbours", "-level", "2", "6"}).out, "5 7 12\n");
}

TEST(QtmcellHierarchy, ParentAndChildrenAgreeWithTheLibrary) {
  std::mt19937_64 random(42);
  for (int level : {1, 3, 13, 23, 24}) {
    std::vector<grid::Code> codes;
    if (level <= 3) {
      for (grid::Code c = 0; c < grid::cell_count(level); ++c) codes.push_back(c);
    } else {
      std::uniform_int_distribution<grid::Code> any(0, grid::cell_count(level) - 1);
      for (int k = 0; k < 300; ++k) codes.push_back(any(random));
    }
    std::string input;
    for (grid::Code c : codes) input += std::to_string(c) + "\n";

    const Result parents = run({"parent", "-level", level_arg(level)}, input);
    ASSERT_EQ(parents.status, 0) << parents.err;
    const std::vector<std::string> p = lines_of(parents.out);
    ASSERT_EQ(p.size(), codes.size());
    for (std::size_t k = 0; k < codes.size(); ++k) EXPECT_EQ(p[k], std::to_string(grid::parent(codes[k], level)));

    if (level == grid::kMaxLevel) continue;
    const Result children = run({"children", "-level", level_arg(level)}, input);
    ASSERT_EQ(children.status, 0) << children.err;
    const std::vector<std::string> c = lines_of(children.out);
    ASSERT_EQ(c.size(), codes.size());
    for (std::size_t k = 0; k < codes.size(); ++k) {
      grid::Code four[4];
      grid::children(codes[k], level, four);
      EXPECT_EQ(c[k], std::to_string(four[0]) + " " + std::to_string(four[1]) + " " + std::to_string(four[2]) + " " +
                          std::to_string(four[3]));
    }
  }
}

TEST(QtmcellDecode, CentresEncodeBackToTheirCellAtLevel24) {
  // The printed digits must be enough to find the cell again, even at the finest level.
  std::mt19937_64 random(7);
  std::uniform_int_distribution<grid::Code> any(0, grid::cell_count(24) - 1);
  std::vector<std::string> args{"decode", "-level", "24"};
  for (int k = 0; k < 500; ++k) args.push_back(std::to_string(any(random)));
  args.push_back("0");                                           // a pole cell
  args.push_back(std::to_string(grid::cell_count(24) - 1));      // the last cell
  const Result decoded = run(args);
  ASSERT_EQ(decoded.status, 0) << decoded.err;
  std::string positions;
  std::vector<std::string> codes;
  for (const std::string& line : lines_of(decoded.out)) {
    const std::vector<std::string> f = fields_of(line);
    ASSERT_EQ(f.size(), 6u);
    codes.push_back(f[0]);
    positions += f[4] + " " + f[5] + "\n";
  }
  const Result encoded = run({"encode", "-level", "24"}, positions);
  ASSERT_EQ(encoded.status, 0) << encoded.err;
  EXPECT_EQ(lines_of(encoded.out), codes);
}

TEST(QtmcellPolygon, WktRingsAreClosedAndHoldTheTestvectorVertices) {
  for (const auto& [level, rows] : by_level("cells.csv")) {
    std::vector<std::string> args{"polygon", "-level", level_arg(level)};
    for (const auto& row : rows) args.push_back(row.at("code"));
    const Result r = run(args);
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.out);
    ASSERT_EQ(lines.size(), rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const std::vector<grid::LonLat> ring = wkt_ring(lines[k]);
      const bool pole_cell = rows[k].at("row") == "0";
      ASSERT_EQ(ring.size(), pole_cell ? 5u : 4u) << lines[k];
      EXPECT_EQ(ring.front().lon, ring.back().lon) << lines[k];
      EXPECT_EQ(ring.front().lat, ring.back().lat) << lines[k];
      double area2 = 0.0;  // twice the signed area in lon/lat: > 0 counter-clockwise
      for (std::size_t q = 0; q + 1 < ring.size(); ++q) {
        area2 += ring[q].lon * ring[q + 1].lat - ring[q + 1].lon * ring[q].lat;
      }
      EXPECT_GT(area2, 0.0) << lines[k];
      for (const char* v : {"v0", "v1", "v2"}) {
        const double lon = std::stod(rows[k].at(std::string(v) + "_lon"));
        const double lat = std::stod(rows[k].at(std::string(v) + "_lat"));
        bool found = false;
        for (const grid::LonLat& p : ring) found |= std::fabs(p.lon - lon) < 1e-9 && std::fabs(p.lat - lat) < 1e-9;
        EXPECT_TRUE(found) << lines[k] << " lacks " << v << " (" << lon << " " << lat << ")";
      }
    }
  }
}

TEST(QtmcellPolygon, PoleCellIsAQuadrilateralReachingThePole) {
  const Result r = run({"polygon", "-level", "1", "0", "16"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "POLYGON ((0 90,0 45,90 45,90 90,0 90))\nPOLYGON ((90 -90,90 -45,0 -45,0 -90,90 -90))\n");
}

TEST(QtmcellPolygon, GeoJsonIsAPolygonObjectOnOneLine) {
  for (const char* option : {"-f", "-of", "--of"}) {
    const Result r = run({"polygon", "-level", "3", option, "GeoJSON", "0", "100", "511"});
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> lines = lines_of(r.out);
    ASSERT_EQ(lines.size(), 3u);
    static const std::regex number(R"(-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][-+]?[0-9]+)?)");
    for (const std::string& line : lines) {
      // Replace each JSON number by N, then check the structure.
      const std::string shape = std::regex_replace(line, number, "N");
      const std::string pattern = R"(^\{"type":"Polygon","coordinates":\[\[(\[N,N\],){3,4}\[N,N\]\]\]\}$)";
      EXPECT_TRUE(std::regex_match(shape, std::regex(pattern))) << line;
      // First and last positions are equal: the ring is closed.
      const std::size_t first = line.find("[[[") + 3, last = line.rfind('[') + 1;
      EXPECT_EQ(line.substr(first, line.find(']', first) - first), line.substr(last, line.find(']', last) - last)) << line;
    }
    EXPECT_EQ(lines[0], R"({"type":"Polygon","coordinates":[[[0,90],[0,78.75],[90,78.75],[90,90],[0,90]]]})");
  }
}

// Bad input: exit 1, a message naming the token and where it was, the good lines printed.
struct BadCase {
  std::vector<std::string> args;
  std::string input;
  std::string expected_out;
  std::vector<std::string> expected_err;  // substrings
};

TEST(QtmcellErrors, BadInputIsReportedAndSkipped) {
  const std::vector<BadCase> cases = {
      // Bad levels: nothing can be done.
      {{"decode", "-level", "25", "1"}, "", "", {"argument 3", "'25'", "level 25"}},
      {{"decode", "-level", "x", "1"}, "", "", {"argument 3", "'x'"}},
      {{"decode", "-level", "-1", "1"}, "", "", {"argument 3", "'-1'"}},
      {{"decode", "-level", "3.5", "1"}, "", "", {"argument 3", "'3.5'"}},
      {{"decode", "-level", "99999999999999999999", "1"}, "", "", {"argument 3", "'99999999999999999999'"}},
      {{"parent", "-level", "0", "1"}, "", "", {"argument 3", "'0'", "level 0", "no parent"}},
      {{"children", "-level", "24", "1"}, "", "", {"argument 3", "'24'", "no children"}},
      // Bad codes on the command line, among good ones.
      {{"decode", "-level", "1", "5", "32", "7"}, "", "5 1 1 0 108 15\n7 1 1 2 162 15\n", {"argument 5", "'32'", "out of range"}},
      {{"parent", "-level", "1", "12abc", "5"}, "", "1\n", {"argument 4", "'12abc'"}},
      {{"children", "-level", "1", "-5", "0"}, "", "0 1 2 3\n", {"argument 4", "'-5'", "negative"}},
      {{"neighbours", "-level", "2", "99999999999999999999999", "6"}, "", "5 7 12\n", {"argument 4", "'99999999999999999999999'"}},
      {{"polygon", "-level", "0", "8", "0x1", "1.0", "0"}, "", "POLYGON ((0 90,0 0,90 0,90 90,0 90))\n", {"argument 4", "'8'", "argument 5", "'0x1'", "argument 6", "'1.0'"}},
      // Bad codes on stdin: line numbers count every line.
      {{"decode", "-level", "1"}, "5\n\nabc 7\n# comment\n40\n", "5 1 1 0 108 15\n7 1 1 2 162 15\n", {"line 3", "'abc'", "line 5", "'40'"}},
      // Bad positions on the command line.
      {{"encode", "-level", "0", "10", "95", "10", "20"}, "", "0\n", {"argument 5", "'95'", "latitude"}},
      {{"encode", "-level", "0", "abc", "20", "10", "20"}, "", "0\n", {"argument 4", "'abc'"}},
      {{"encode", "-level", "0", "nan", "20", "10", "inf", "10", "-90.5", "100", "20"}, "", "1\n",
       {"argument 4", "'nan'", "argument 7", "'inf'", "argument 9", "'-90.5'"}},
      // Bad positions on stdin.
      {{"encode", "-level", "0"}, "10 20\n10,95\nabc 20\n1 2 3\n100,20\n10,\n", "0\n1\n",
       {"line 2", "'95'", "line 3", "'abc'", "line 4", "'1 2 3'", "line 6"}},
  };
  for (const BadCase& c : cases) {
    const Result r = run(c.args, c.input);
    std::string what;
    for (const std::string& a : c.args) what += a + " ";
    EXPECT_EQ(r.status, 1) << what;
    EXPECT_EQ(r.out, c.expected_out) << what;
    for (const std::string& part : c.expected_err) EXPECT_NE(r.err.find(part), std::string::npos) << what << ": " << r.err;
  }
}

TEST(QtmcellErrors, UsageErrorsExit2WithTheUsage) {
  const std::vector<std::vector<std::string>> cases = {
      {},
      {"frobnicate", "-level", "3"},
      {"decode", "1"},
      {"decode", "-level"},
      {"decode", "-level", "3", "-x", "1"},
      {"decode", "-level", "3", "-f", "wkt", "1"},
      {"polygon", "-level", "3", "-f", "kml", "1"},
      {"encode", "-level", "3", "10"},
      {"-level", "3", "decode", "1"},
  };
  for (const auto& args : cases) {
    const Result r = run(args, "1\n");
    std::string what;
    for (const std::string& a : args) what += a + " ";
    EXPECT_EQ(r.status, 2) << what;
    EXPECT_EQ(r.out, "") << what;
    EXPECT_NE(r.err.find("Usage:"), std::string::npos) << what << ": " << r.err;
    EXPECT_NE(r.err.find("qtmcell decode -level"), std::string::npos) << what;
  }
}

TEST(QtmcellOptions, DoubleDashOptionsAndEndOfOptions) {
  EXPECT_EQ(run({"decode", "--level", "2", "6"}).out, run({"decode", "-level", "2", "6"}).out);
  EXPECT_EQ(run({"decode", "6", "-level", "2"}).out, run({"decode", "-level", "2", "6"}).out);
  const Result r = run({"encode", "-level", "1", "--", "-100", "-10"});
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, std::to_string(grid::lonlat_to_code(-100, -10, 1)) + "\n");
  EXPECT_EQ(run({"neighbors", "-level", "2", "6"}).out, "5 7 12\n");
}

TEST(QtmcellHelp, HelpPrintsTheManualAndExits0) {
  for (const char* option : {"--help", "-help", "-h"}) {
    const Result r = run({option});
    EXPECT_EQ(r.status, 0);
    EXPECT_EQ(r.err, "");
    for (const char* part : {"SYNOPSIS", "DESCRIPTION", "EXIT STATUS", "EXAMPLES", "encode", "decode", "neighbours",
                             "parent", "children", "polygon", "geojson", "-level"}) {
      EXPECT_NE(r.out.find(part), std::string::npos) << option << " lacks " << part;
    }
  }
  // --help wins over a command line that is otherwise wrong.
  EXPECT_EQ(run({"decode", "-level", "x", "--help"}).status, 0);
}

TEST(QtmcellHelp, Version) {
  const Result r = run({"--version"});
  EXPECT_EQ(r.status, 0);
  EXPECT_EQ(r.out, std::string("qtmcell (qtmvoronoi) ") + QTMV_VERSION_STRING + "\n");
}

TEST(QtmcellManPage, IsMadeFromTheSamePod) {
  const std::string page = read_all(QTMCELL_MAN_PAGE);
  ASSERT_FALSE(page.empty()) << QTMCELL_MAN_PAGE;
  EXPECT_NE(page.find(".TH QTMCELL 1"), std::string::npos);
  for (const char* section : {"NAME", "SYNOPSIS", "DESCRIPTION", "COMMANDS", "OPTIONS", "EXIT STATUS", "EXAMPLES", "SEE ALSO"}) {
    // Older pod2man quotes every heading (.SH "NAME"), newer ones only those with spaces.
    const bool quoted = page.find(std::string(".SH \"") + section + "\"") != std::string::npos;
    const bool plain = page.find(std::string(".SH ") + section + "\n") != std::string::npos;
    EXPECT_TRUE(quoted || plain) << section;
  }
  EXPECT_EQ(page.find("POD ERRORS"), std::string::npos);
}

}  // namespace
