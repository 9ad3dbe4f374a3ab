// Unit tests of qtmcell's parsing and formatting, called directly.
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "qtmcell_core.hpp"

namespace {

using namespace qtmv::qtmcell;

TEST(QtmcellCore, ParseLevel) {
  EXPECT_EQ(parse_level("0"), 0);
  EXPECT_EQ(parse_level("24"), 24);
  for (const char* bad : {"", "25", "-1", "3.0", "3 ", " 3", "x", "1e1", "99999999999999"}) {
    EXPECT_THROW(parse_level(bad), TokenError) << "'" << bad << "'";
  }
}

TEST(QtmcellCore, ParseCode) {
  EXPECT_EQ(parse_code("0", 0), 0u);
  EXPECT_EQ(parse_code("7", 0), 7u);
  EXPECT_EQ(parse_code("007", 0), 7u);
  const std::string last = std::to_string(qtmv::grid::cell_count(24) - 1);
  EXPECT_EQ(parse_code(last, 24), qtmv::grid::cell_count(24) - 1);
  for (const char* bad : {"", "8", "-1", "+1", "12abc", "1.0", "1e2", "0x1", " 1", "18446744073709551616"}) {
    EXPECT_THROW(parse_code(bad, 0), TokenError) << "'" << bad << "'";
  }
  try {
    parse_code("12abc", 3);
    FAIL();
  } catch (const TokenError& e) {
    EXPECT_EQ(e.token(), "12abc");
  }
}

TEST(QtmcellCore, ParseNumbersAndLatitudes) {
  EXPECT_EQ(parse_number("-122.5"), -122.5);
  EXPECT_EQ(parse_number("+3"), 3.0);
  EXPECT_EQ(parse_number("1e-07"), 1e-7);
  EXPECT_EQ(parse_number(".5"), 0.5);
  for (const char* bad : {"", "+", "+-1", "abc", "1,5", "nan", "inf", "-inf", "infinity", "1e999", "0x10", "1 "}) {
    EXPECT_THROW(parse_number(bad), TokenError) << "'" << bad << "'";
  }
  EXPECT_EQ(parse_latitude("-90"), -90.0);
  EXPECT_EQ(parse_latitude("90"), 90.0);
  EXPECT_THROW(parse_latitude("90.0000001"), TokenError);
  EXPECT_THROW(parse_latitude("-95"), TokenError);
}

TEST(QtmcellCore, SplitPositionLine) {
  using V = std::vector<std::string>;
  EXPECT_EQ(split_position_line("1 2"), (V{"1", "2"}));
  EXPECT_EQ(split_position_line("1,2"), (V{"1", "2"}));
  EXPECT_EQ(split_position_line("\t1 ,  2\r"), (V{"1", "2"}));
  for (const char* bad : {"", "1", "1 2 3", "1,2,3", "1,", ",2", "1 2,3"}) {
    EXPECT_THROW(split_position_line(bad), TokenError) << "'" << bad << "'";
  }
}

TEST(QtmcellCore, FormatDegrees) {
  EXPECT_EQ(format_degrees(45.0), "45");
  EXPECT_EQ(format_degrees(-0.0), "0");
  EXPECT_EQ(format_degrees(-122.427769985975), "-122.427769985975");
  EXPECT_EQ(format_degrees(1.0 / 3.0), "0.333333333333333");  // 15 significant digits
}

TEST(QtmcellCore, CommandLine) {
  const Options o = parse_command_line({"polygon", "--level", "5", "-122", "-of", "GEOJSON", "--", "-level"});
  EXPECT_EQ(o.command, Command::kPolygon);
  EXPECT_EQ(o.level.text, "5");
  EXPECT_EQ(o.level.index, 3);
  EXPECT_EQ(o.format, PolygonFormat::kGeoJson);
  ASSERT_EQ(o.inputs.size(), 2u);
  EXPECT_EQ(o.inputs[0].text, "-122");  // a negative number is an input, not an option
  EXPECT_EQ(o.inputs[0].index, 4);
  EXPECT_EQ(o.inputs[1].text, "-level");  // after --
  EXPECT_EQ(o.inputs[1].index, 8);
  EXPECT_TRUE(parse_command_line({"decode", "-level", "x", "-h"}).help);
  EXPECT_TRUE(parse_command_line({"--version"}).version);
  EXPECT_THROW(parse_command_line({}), UsageError);
  EXPECT_THROW(parse_command_line({"decode"}), UsageError);
  EXPECT_THROW(parse_command_line({"decode", "-level", "1", "-q"}), UsageError);
  EXPECT_THROW(parse_command_line({"encode", "-level", "1", "1"}), UsageError);
}

TEST(QtmcellCore, MainWithStreams) {
  std::istringstream in("6\nxyz\n");
  std::ostringstream out, err;
  EXPECT_EQ(qtmcell_main({"neighbours", "-level", "2"}, in, out, err), kExitBadInput);
  EXPECT_EQ(out.str(), "5 7 12\n");
  EXPECT_EQ(err.str(), "qtmcell: line 2: 'xyz': not a code: codes are decimal integers\n");
}

}  // namespace
