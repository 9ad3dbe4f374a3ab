// qtmcell: the QTM grid on the command line. Parsing and per-input processing live here,
// apart from main(), so that the tests can call them directly.
#pragma once

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "grid/qtm.hpp"

namespace qtmv::qtmcell {

enum class Command { kEncode, kDecode, kNeighbours, kParent, kChildren, kPolygon };
enum class PolygonFormat { kWkt, kGeoJson };

/// A command-line argument and its position in argv (the command is argument 1).
struct Argument {
  std::string text;
  int index = 0;
};

/// What the command line asks for. The level is kept as text: a bad level is an input
/// error (exit 1) reported by run(), not a usage error.
struct Options {
  bool help = false;
  bool version = false;
  Command command = Command::kDecode;
  Argument level;
  PolygonFormat format = PolygonFormat::kWkt;
  std::vector<Argument> inputs;  ///< codes, or coordinates for encode; empty: read stdin
};

/// A malformed command line (exit 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One bad input token (exit 1); what() says what is wrong with it.
class TokenError : public std::invalid_argument {
 public:
  TokenError(std::string token, const std::string& reason) : std::invalid_argument(reason), token_(std::move(token)) {}
  const std::string& token() const { return token_; }

 private:
  std::string token_;
};

/// Exit statuses, as the man page documents them.
constexpr int kExitOk = 0;
constexpr int kExitBadInput = 1;
constexpr int kExitUsage = 2;

/// Parses argv[1..] (args[0] is argv[1]). Throws UsageError.
Options parse_command_line(const std::vector<std::string>& args);

/// A level 0..24 in decimal. Throws TokenError.
int parse_level(std::string_view token);
/// A cell code of the level, in decimal. Throws TokenError.
grid::Code parse_code(std::string_view token, int level);
/// A finite decimal number. Throws TokenError.
double parse_number(std::string_view token);
/// A latitude: a finite number in [-90, 90]. Throws TokenError.
double parse_latitude(std::string_view token);
/// The two fields of an encode input line, "lon lat" or "lon,lat". Throws TokenError.
std::vector<std::string> split_position_line(std::string_view line);

/// A coordinate with 15 significant digits, never "-0".
std::string format_degrees(double value);

/// Output line for one position (encode).
std::string encode_line(double lon, double lat, int level);
/// Output line for one valid code of the level (every command but encode).
std::string code_line(Command command, grid::Code code, int level, PolygonFormat format);

/// Does what the options ask, reading stdin when they hold no inputs. Bad inputs get a message
/// on err and are skipped; returns the exit status.
int run(const Options& options, std::istream& in, std::ostream& out, std::ostream& err);

/// The whole program: parses args (argv[1..]), handles --help, --version and usage errors,
/// then run(). Returns the exit status.
int qtmcell_main(const std::vector<std::string>& args, std::istream& in, std::ostream& out, std::ostream& err);

}  // namespace qtmv::qtmcell
