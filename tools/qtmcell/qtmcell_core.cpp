#include "qtmcell_core.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <istream>
#include <ostream>

#include "grid/qtm_checks.hpp"
#include "qtmcell_usage.hpp"  // generated from man/qtmcell.pod
#include "qtmv_version.hpp"

namespace qtmv::qtmcell {

namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split_spaces(std::string_view s) {
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    if (i > start) fields.push_back(s.substr(start, i - start));
  }
  return fields;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Negative numbers are values, not options, so that "encode -level 3 -122.4 37.8" works.
bool looks_like_option(const std::string& s) {
  return s.size() > 1 && s[0] == '-' && !is_digit(s[1]) && s[1] != '.';
}

// GDAL style: "--level" means "-level".
std::string option_name(const std::string& s) { return s.size() > 2 && s[0] == '-' && s[1] == '-' ? s.substr(1) : s; }

struct CommandName {
  const char* name;
  Command command;
};
constexpr CommandName kCommands[] = {
    {"encode", Command::kEncode},         {"decode", Command::kDecode},   {"neighbours", Command::kNeighbours},
    {"neighbors", Command::kNeighbours},  {"parent", Command::kParent},   {"children", Command::kChildren},
    {"polygon", Command::kPolygon},
};

std::string join_codes(const grid::Code* codes, int n) {
  std::string s;
  for (int k = 0; k < n; ++k) {
    if (k > 0) s += ' ';
    s += std::to_string(codes[k]);
  }
  return s;
}

std::string polygon_text(const grid::Cell& cell, int level, PolygonFormat format) {
  grid::LonLat ring[grid::kMaxPolygonCorners + 1];
  int n = grid::cell_polygon(cell, level, ring);
  ring[n++] = ring[0];  // close the ring, as WKT and GeoJSON require
  std::string s = format == PolygonFormat::kWkt ? "POLYGON ((" : R"({"type":"Polygon","coordinates":[[)";
  for (int k = 0; k < n; ++k) {
    if (k > 0) s += ',';
    if (format == PolygonFormat::kWkt) {
      s += format_degrees(ring[k].lon) + ' ' + format_degrees(ring[k].lat);
    } else {
      s += '[' + format_degrees(ring[k].lon) + ',' + format_degrees(ring[k].lat) + ']';
    }
  }
  s += format == PolygonFormat::kWkt ? "))" : "]]}";
  return s;
}

// Writes one error message; returns kExitBadInput for the caller to keep.
int report(std::ostream& out, std::ostream& err, const std::string& where, const TokenError& e) {
  out.flush();  // keep stdout and stderr in order on a terminal
  err << "qtmcell: " << where << ": '" << e.token() << "': " << e.what() << '\n';
  return kExitBadInput;
}

std::string argument_place(const Argument& a) { return "argument " + std::to_string(a.index); }
std::string line_place(long line) { return "line " + std::to_string(line); }

// A line of stdin to process, or false for a blank line or a comment.
bool content_of(const std::string& line, std::string_view* content) {
  *content = trim(line);
  return !content->empty() && content->front() != '#';
}

}  // namespace

Options parse_command_line(const std::vector<std::string>& args) {
  Options options;
  // --help and --version win over everything else, as in GDAL.
  for (const std::string& arg : args) {
    if (arg == "--") break;
    const std::string name = option_name(arg);
    if (name == "-help" || name == "-h") {
      options.help = true;
      return options;
    }
    if (name == "-version") {
      options.version = true;
      return options;
    }
  }
  if (args.empty()) throw UsageError("no command given");
  if (looks_like_option(args[0])) throw UsageError("the command must come first, before '" + args[0] + "'");
  bool known = false;
  for (const CommandName& c : kCommands) {
    if (args[0] == c.name) {
      options.command = c.command;
      known = true;
    }
  }
  if (!known) throw UsageError("unknown command '" + args[0] + "'");

  bool options_ended = false;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& arg = args[i];
    const int index = static_cast<int>(i) + 1;  // args[0] is argv[1]
    if (options_ended || !looks_like_option(arg)) {
      options.inputs.push_back({arg, index});
      continue;
    }
    if (arg == "--") {
      options_ended = true;
      continue;
    }
    const std::string name = option_name(arg);
    const bool is_level = name == "-level";
    const bool is_format = name == "-f" || name == "-of";
    if (!is_level && !is_format) throw UsageError("unknown option '" + arg + "'");
    if (i + 1 >= args.size()) throw UsageError("option '" + arg + "' needs a value");
    const std::string& value = args[++i];
    if (is_level) {
      options.level = {value, index + 1};
      continue;
    }
    if (options.command != Command::kPolygon) throw UsageError("option '" + arg + "' is for the polygon command only");
    const std::string format = lower(value);
    if (format == "wkt") {
      options.format = PolygonFormat::kWkt;
    } else if (format == "geojson") {
      options.format = PolygonFormat::kGeoJson;
    } else {
      throw UsageError("unknown format '" + value + "' for " + arg + ": use wkt or geojson");
    }
  }
  if (options.level.index == 0) throw UsageError("-level is required");
  if (options.command == Command::kEncode && options.inputs.size() % 2 != 0) {
    throw UsageError("encode takes coordinates in pairs, LON LAT: " + std::to_string(options.inputs.size()) +
                     " given");
  }
  return options;
}

int parse_level(std::string_view token) {
  const std::string text(token);
  int level = -1;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, level);
  if (ec == std::errc::invalid_argument || ptr != end) {
    throw TokenError(text, "not a level: levels are whole numbers from 0 to 24");
  }
  if (ec == std::errc::result_out_of_range) throw TokenError(text, "out of range: levels 0 to 24 are supported");
  try {
    grid::require_level(level);
  } catch (const std::invalid_argument& e) {
    throw TokenError(text, e.what());
  }
  return level;
}

grid::Code parse_code(std::string_view token, int level) {
  const std::string text(token);
  if (token.size() > 1 && token[0] == '-' && is_digit(token[1])) {
    throw TokenError(text, "not a code: codes are not negative");
  }
  grid::Code code = 0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, code);
  if (ec == std::errc::invalid_argument || ptr != end) throw TokenError(text, "not a code: codes are decimal integers");
  if (ec == std::errc::result_out_of_range) {  // beyond 64 bits
    throw TokenError(text, "out of range at level " + std::to_string(level) + ": codes run from 0 to " +
                               std::to_string(grid::cell_count(level) - 1));
  }
  try {
    grid::require_code(code, level);
  } catch (const std::invalid_argument& e) {
    throw TokenError(text, e.what());
  }
  return code;
}

double parse_number(std::string_view token) {
  std::string_view digits = token;
  // from_chars takes no '+'; allow one, but not "+-1".
  if (digits.size() > 1 && digits[0] == '+' && digits[1] != '-' && digits[1] != '+') digits.remove_prefix(1);
  double value = 0.0;
  const char* end = digits.data() + digits.size();
  const auto [ptr, ec] = std::from_chars(digits.data(), end, value, std::chars_format::general);
  if (ec == std::errc::invalid_argument || ptr != end) throw TokenError(std::string(token), "not a number");
  if (ec == std::errc::result_out_of_range) throw TokenError(std::string(token), "number too large or too small");
  if (!std::isfinite(value)) throw TokenError(std::string(token), "not a finite number");
  return value;
}

double parse_latitude(std::string_view token) {
  const double lat = parse_number(token);
  if (!(lat >= -90.0 && lat <= 90.0)) throw TokenError(std::string(token), "latitude out of range: it must lie in [-90, 90]");
  return lat;
}

std::vector<std::string> split_position_line(std::string_view line) {
  const std::string_view text = trim(line);
  std::vector<std::string> fields;
  const std::size_t comma = text.find(',');
  if (comma != std::string_view::npos) {
    const std::string_view lon = trim(text.substr(0, comma));
    const std::string_view lat = trim(text.substr(comma + 1));
    if (!lon.empty() && !lat.empty() && split_spaces(lon).size() == 1 && split_spaces(lat).size() == 1 &&
        lat.find(',') == std::string_view::npos) {
      fields = {std::string(lon), std::string(lat)};
    }
  } else {
    for (std::string_view f : split_spaces(text)) fields.emplace_back(f);
  }
  if (fields.size() != 2) throw TokenError(std::string(text), "expected a position as 'lon lat' or 'lon,lat'");
  return fields;
}

std::string format_degrees(double value) {
  char buffer[32];
  // 15 significant digits survive a round trip through decimal; + 0.0 turns -0 into 0.
  std::snprintf(buffer, sizeof buffer, "%.15g", value + 0.0);
  return buffer;
}

std::string encode_line(double lon, double lat, int level) {
  return std::to_string(grid::lonlat_to_code(lon, lat, level));
}

std::string code_line(Command command, grid::Code code, int level, PolygonFormat format) {
  const grid::Cell cell = grid::cell_of(code, level);
  switch (command) {
    case Command::kDecode: {
      const grid::LonLat centre = grid::cell_centre(cell, level);
      return std::to_string(code) + ' ' + std::to_string(cell.octant) + ' ' + std::to_string(cell.row) + ' ' +
             std::to_string(cell.col) + ' ' + format_degrees(centre.lon) + ' ' + format_degrees(centre.lat);
    }
    case Command::kNeighbours: {
      grid::Code n[3];
      grid::neighbours(code, level, n);
      return join_codes(n, 3);
    }
    case Command::kParent:
      return std::to_string(grid::parent(code, level));
    case Command::kChildren: {
      grid::Code c[4];
      grid::children(code, level, c);
      return join_codes(c, 4);
    }
    case Command::kPolygon:
      return polygon_text(cell, level, format);
    case Command::kEncode:
      break;
  }
  throw std::logic_error("code_line: encode takes positions, not codes");
}

int run(const Options& options, std::istream& in, std::ostream& out, std::ostream& err) {
  const Command command = options.command;
  int level = 0;
  try {
    level = parse_level(options.level.text);
    if (command == Command::kParent && level == grid::kMinLevel) {
      throw TokenError(options.level.text, "level 0 cells have no parent: parent takes levels 1 to 24");
    }
    if (command == Command::kChildren && level == grid::kMaxLevel) {
      throw TokenError(options.level.text, "level 24 is the finest, its cells have no children: children takes levels 0 to 23");
    }
  } catch (const TokenError& e) {
    return report(out, err, argument_place(options.level), e);
  }

  int status = kExitOk;
  if (command == Command::kEncode) {
    const std::vector<Argument>& args = options.inputs;
    for (std::size_t k = 0; k + 1 < args.size(); k += 2) {
      const Argument* current = &args[k];
      try {
        const double lon = parse_number(args[k].text);
        current = &args[k + 1];
        const double lat = parse_latitude(args[k + 1].text);
        out << encode_line(lon, lat, level) << '\n';
      } catch (const TokenError& e) {
        status = report(out, err, argument_place(*current), e);
      }
    }
  } else {
    for (const Argument& a : options.inputs) {
      try {
        out << code_line(command, parse_code(a.text, level), level, options.format) << '\n';
      } catch (const TokenError& e) {
        status = report(out, err, argument_place(a), e);
      }
    }
  }

  if (options.inputs.empty()) {
    std::string line;
    long line_number = 0;
    while (std::getline(in, line)) {
      ++line_number;
      std::string_view content;
      if (!content_of(line, &content)) continue;
      if (command == Command::kEncode) {
        try {
          const std::vector<std::string> fields = split_position_line(content);
          const double lon = parse_number(fields[0]);
          const double lat = parse_latitude(fields[1]);
          out << encode_line(lon, lat, level) << '\n';
        } catch (const TokenError& e) {
          status = report(out, err, line_place(line_number), e);
        }
        continue;
      }
      for (std::string_view token : split_spaces(content)) {
        try {
          out << code_line(command, parse_code(token, level), level, options.format) << '\n';
        } catch (const TokenError& e) {
          status = report(out, err, line_place(line_number), e);
        }
      }
    }
    if (in.bad()) {
      err << "qtmcell: cannot read standard input\n";
      status = kExitBadInput;
    }
  }

  out.flush();
  if (!out) {
    err << "qtmcell: cannot write standard output\n";
    status = kExitBadInput;
  }
  return status;
}

int qtmcell_main(const std::vector<std::string>& args, std::istream& in, std::ostream& out, std::ostream& err) {
  Options options;
  try {
    options = parse_command_line(args);
  } catch (const UsageError& e) {
    err << "qtmcell: " << e.what() << "\n" << kUsageText << "Try 'qtmcell --help' for the full help.\n";
    return kExitUsage;
  }
  if (options.help || options.version) {
    if (options.help) {
      out << kHelpText;
    } else {
      out << "qtmcell (qtmvoronoi) " << QTMV_VERSION_STRING << '\n';
    }
    out.flush();
    return out ? kExitOk : kExitBadInput;
  }
  return run(options, in, out, err);
}

}  // namespace qtmv::qtmcell
