// qtmvoronoi: spherical Voronoi diagrams on the QTM grid, on the command line. Parsing, the
// progress display and the signal handling live here, apart from main(), so that the tests can
// call them; the work is the library's run_voronoi() (src/voronoi.hpp).
#pragma once

#include <csignal>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "voronoi.hpp"

namespace qtmv::qtmvoronoi {

/// What the command line asks for.
struct Options {
  bool help = false;
  bool version = false;
  bool quiet = false;     ///< -q: no progress, no informative lines (warnings and errors still)
  bool progress = false;  ///< -progress: progress even when stderr is not a terminal
  std::string source, destination;
  VoronoiOptions run;     ///< everything the library takes (progress and messages set by the tool)
};

/// A malformed command line (exit 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Exit statuses, as the man page documents them.
constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

/// Parses argv[1..] (args[0] is argv[1]) after GDAL's generic options are gone. Throws UsageError.
Options parse_command_line(const std::vector<std::string>& args);

/// GDAL's text progress (0...10...20...100 - done.) on a stream of our choice: GDALTermProgress
/// writes to stdout, which /vsistdout/ pipelines need for the data.
class TermProgress {
 public:
  explicit TermProgress(std::FILE* out) : out_(out) {}
  void update(double fraction);
  /// Whether a line is open (some dots printed, no "done" yet): a message must start a new line.
  bool mid_line() const { return ticks_ >= 0 && ticks_ < 40; }
  void break_line();

 private:
  std::FILE* out_;
  int ticks_ = -1;
};

/// Set by SIGINT/SIGTERM (the handlers that install_signal_handlers() puts in place); the
/// progress callback returns false once it is set, so the run stops and cleans up.
extern volatile std::sig_atomic_t g_signal;
/// Installs the handlers; a second signal of either kind gets the default action (kill).
void install_signal_handlers();

/// The whole program: GDAL's generic options (--config, --formats, ...), --help, --version,
/// parsing, signals, the run, messages. Returns the exit status.
int qtmvoronoi_main(int argc, char** argv);

}  // namespace qtmv::qtmvoronoi
