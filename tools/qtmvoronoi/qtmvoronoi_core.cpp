#include "common/device_spec.hpp"
#include "common/visible_devices.hpp"
#include "qtmvoronoi_core.hpp"

#include <cpl_conv.h>
#include <gdal.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>

#include "qtmv_version.hpp"
#include "qtmvoronoi_usage.hpp"  // generated from man/qtmvoronoi.pod
#include "write/raster_bands.hpp"
#include "write/raster_writer.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::qtmvoronoi {

volatile std::sig_atomic_t g_signal = 0;

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Negative numbers are values, not options.
bool looks_like_option(const std::string& s) {
  return s.size() > 1 && s[0] == '-' && !is_digit(s[1]) && s[1] != '.';
}

// GDAL style: "--level" means "-level"; names are not case-sensitive.
std::string option_name(const std::string& s) {
  return lower(s.size() > 2 && s[0] == '-' && s[1] == '-' ? s.substr(1) : s);
}

bool is_help(const std::string& name) { return name == "-help" || name == "-h" || name == "-?"; }

int parse_int(const std::string& option, const std::string& text, int low, int high, const char* what) {
  int value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr != end || value < low || value > high) {
    throw UsageError(option + ": '" + text + "' is not " + what);
  }
  return value;
}

double parse_positive(const std::string& option, const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(value) || value <= 0) {
    throw UsageError(option + ": '" + text + "' is not a positive number");
  }
  return value;
}

std::string name_value(const std::string& option, const std::string& text) {
  if (text.find('=') == std::string::npos || text.front() == '=') {
    throw UsageError(option + ": '" + text + "' is not NAME=VALUE");
  }
  return text;
}

// -sql @file reads the statement from a file, as in ogr2ogr.
std::string sql_text(const std::string& text) {
  if (text.empty() || text.front() != '@') return text;
  // Not /dev/zero or a FIFO: read to its end, that would never end.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(text.substr(1), ec)) {
    throw UsageError("-sql: cannot read '" + text.substr(1) + "': " +
                     (std::filesystem::exists(text.substr(1), ec) ? "not a regular file" : "no such file"));
  }
  std::ifstream in(text.substr(1));
  if (!in) throw UsageError("-sql: cannot read '" + text.substr(1) + "'");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> items;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    items.push_back(item);
  }
  return items;
}

// Options that shape a dataset: a tile job, which writes a tile product, refuses them.
bool shapes_output(const std::string& name) {
  return name == "-of" || name == "-f" || name == "-lco" || name == "-dsco" || name == "-co" || name == "-ot" ||
         name == "-layers" || name == "-raster" || name == "-tr" || name == "-ts" || name == "-vertices" ||
         name == "-bands";
}

// One option on the command line, as written (arg) and as named (option_name), and its values.
struct OptionAt {
  const std::string& arg;
  const std::string& name;
  const std::vector<std::string>& args;
  std::size_t& i;  // the option's index; value() moves it on to each value taken
  const std::string& value() const {
    if (i + 1 >= args.size()) throw UsageError("option '" + arg + "' needs a value");
    return args[++i];
  }
};

// What the checks after the options need to know of them.
struct ParseState {
  bool tr = false, ts = false, raster_named = false, layers_named = false;
  std::string output_option;  // the first option that shapes a dataset (a tile job writes none)
  std::string raster_option;  // the first option of raster output (a part is vector output)
};

// One parser per option group, each true when the option is one of its group's.

// The reader's options: what to read and how.
bool parse_reader_option(const OptionAt& at, sites::SourceOptions& read) {
  const std::string& name = at.name;
  if (name == "-l") {
    const std::string& layer = at.value();
    if (std::find(read.layers.begin(), read.layers.end(), layer) != read.layers.end()) {
      throw UsageError("-l: layer '" + layer + "' named twice");
    }
    read.layers.push_back(layer);
  } else if (name == "-where") {
    read.where = at.value();
  } else if (name == "-sql") {
    read.sql = sql_text(at.value());
  } else if (name == "-dialect") {
    read.dialect = at.value();
  } else if (name == "-s_srs") {
    read.source_srs = at.value();
  } else if (name == "-edges" || name == "-wrap") {
    const std::string& v = at.value();
    try {
      if (name == "-edges") read.edges = sites::parse_edge_shape(v);
      if (name == "-wrap") read.wrap = sites::parse_wrap_mode(v);
    } catch (const std::exception& e) {
      throw UsageError(e.what());
    }
  } else if (name == "-strict") {
    read.strict = true;
  } else if (name == "-makevalid") {
    read.make_valid = true;
  } else if (name == "-oo") {
    read.open_options.push_back(name_value(at.arg, at.value()));
  } else {
    return false;
  }
  return true;
}

// The labeller's options: level, distance rule, device, algorithm, threads.
bool parse_labeller_option(const OptionAt& at, VoronoiOptions& run) {
  const std::string& name = at.name;
  if (name == "-level") {
    run.level = parse_int(at.arg, at.value(), 0, 24, "a level from 0 to 24");
  } else if (name == "-distance") {
    const std::string& v = at.value();
    try {
      run.rule = sites::parse_distance_rule(v);
    } catch (const std::exception& e) {
      throw UsageError(e.what());
    }
  } else if (name == "-device") {
    const std::string v = lower(at.value());
    try {
      parse_device_spec(v);
    } catch (const std::invalid_argument&) {
      throw UsageError("-device: '" + v + "' is not one of " + device_spec_forms());
    }
    run.device = v;
  } else if (name == "-algorithm") {
    const std::string v = lower(at.value());
    if (v == "auto") {
      run.algorithm = label::Algorithm::automatic;
    } else if (v == "hier") {
      run.algorithm = label::Algorithm::hier;
    } else if (v == "brute") {
      run.algorithm = label::Algorithm::brute;
    } else {
      throw UsageError("-algorithm: '" + v + "' is not one of auto, hier, brute");
    }
  } else if (name == "-threads") {
    run.threads = parse_int(at.arg, at.value(), 1, 4096, "a number of threads");
  } else {
    return false;
  }
  return true;
}

// The vector writer's options, and the output's driver.
bool parse_vector_option(const OptionAt& at, VoronoiOptions& run) {
  const std::string& name = at.name;
  if (name == "-of" || name == "-f") {
    run.format = at.value();
  } else if (name == "-lco") {
    run.vector.layer_options.push_back(name_value(at.arg, at.value()));
  } else if (name == "-dsco") {
    run.vector.dataset_options.push_back(name_value(at.arg, at.value()));
  } else if (name == "-layers") {
    run.vector.layers = split_list(at.value());
    if (const std::string problem = write::check_layer_names(run.vector.layers); !problem.empty()) {
      throw UsageError("-layers: " + problem);
    }
    for (std::size_t k = 0; k < run.vector.layers.size(); ++k) {
      const std::string& layer = run.vector.layers[k];
      if (std::find(run.vector.layers.begin(), run.vector.layers.begin() + k, layer) != run.vector.layers.begin() + k) {
        throw UsageError("-layers: '" + layer + "' named twice");
      }
    }
    if (run.kind == OutputKind::raster) throw UsageError("-layers is for vector output, -raster for raster output");
    if (!run.raster.bands.empty()) throw UsageError("-bands is for raster output, -layers for vector output");
    run.kind = OutputKind::vector;
  } else if (name == "-vertices") {
    const std::string v = lower(at.value());
    if (v != "corners" && v != "all") throw UsageError("-vertices: '" + v + "' is not one of corners, all");
    using Vertices = write::VectorLayers::Vertices;
    run.vector.ring_vertices = v == "all" ? Vertices::all : Vertices::corners;
  } else {
    return false;
  }
  return true;
}

// The raster writer's options.
bool parse_raster_option(const OptionAt& at, VoronoiOptions& run, ParseState& state) {
  const std::string& name = at.name;
  if (name == "-co") {
    run.raster.creation_options.push_back(name_value(at.arg, at.value()));
  } else if (name == "-ot") {
    run.raster.data_type = at.value();
    try {
      write::check_raster_data_type(run.raster.data_type);
    } catch (const std::exception& e) {
      throw UsageError(e.what());
    }
  } else if (name == "-bands") {
    if (!run.raster.bands.empty()) throw UsageError("-bands: given twice; name every band in one list");
    try {
      run.raster.bands = write::parse_raster_bands(at.value());
    } catch (const std::exception& e) {
      throw UsageError(e.what());
    }
    if (run.kind == OutputKind::vector) throw UsageError("-bands is for raster output, -layers for vector output");
  } else if (name == "-raster") {
    const std::string v = lower(at.value());
    if (v == "qtm") {
      run.raster.layout = write::RasterOptions::Layout::qtm;
    } else if (v == "lonlat") {
      run.raster.layout = write::RasterOptions::Layout::lonlat;
    } else {
      throw UsageError("-raster: '" + v + "' is not one of qtm, lonlat");
    }
    state.raster_named = true;
    if (run.kind == OutputKind::vector) throw UsageError("-layers is for vector output, -raster for raster output");
    run.kind = OutputKind::raster;
  } else if (name == "-tr") {
    run.raster.x_resolution = parse_positive(at.arg, at.value());
    run.raster.y_resolution = parse_positive(at.arg, at.value());
    state.tr = true;
  } else if (name == "-ts") {
    run.raster.width = parse_int(at.arg, at.value(), 1, 2147483647, "a positive number of pixels");
    run.raster.height = parse_int(at.arg, at.value(), 1, 2147483647, "a positive number of pixels");
    state.ts = true;
  } else {
    return false;
  }
  return true;
}

// The run's options: tile jobs and merges, the destination, and the tool's own output.
bool parse_run_option(const OptionAt& at, Options& o) {
  const std::string& name = at.name;
  VoronoiOptions& run = o.run;
  if (name == "-tile") {
    const std::string& v = at.value();
    const std::size_t slash = v.find('/');
    if (slash == std::string::npos) throw UsageError("-tile: '" + v + "' is not K/N (tile K of N, from 1)");
    run.tile_count = parse_int(at.arg, v.substr(slash + 1), 1, 2147483647, "K/N with N a positive number of tiles");
    run.tile_index = parse_int(at.arg, v.substr(0, slash), 1, run.tile_count, "K/N with K from 1 to N");
  } else if (name == "-merge") {
    run.merge.push_back(at.value());
  } else if (name == "-part") {
    run.part = true;
  } else if (name == "-overwrite") {
    run.overwrite = true;
  } else if (name == "-q" || name == "-quiet") {
    o.quiet = true;
  } else if (name == "-progress") {
    o.progress = true;
  } else {
    return false;
  }
  return true;
}

// The checks of options given together, once all are read; a pixel size implies -raster lonlat.
void check_option_combinations(VoronoiOptions& run, const ParseState& state) {
  if (state.tr && state.ts) throw UsageError("-tr and -ts exclude each other");
  if (run.tile_count > 0 && !run.merge.empty()) {
    throw UsageError("-tile and -merge exclude each other: tile jobs come first, then one merge of their products");
  }
  if (run.part && run.tile_count == 0) {
    throw UsageError("-part is for a tile job: -tile K/N -part writes the tile's part of the output");
  }
  // A part's layers: those that can be cut at a tile's edges (not voronoi_edges). A raster part
  // takes the raster's options (its output's: run_plan.cpp checks them against the destination).
  if (run.part && !state.layers_named) run.vector.layers = {"regions", "boundary_cells"};
  if (run.tile_count > 0 && !run.part && !state.output_option.empty()) {
    const std::string name = option_name(state.output_option);
    if (name == "-co" || name == "-ot" || name == "-raster" || name == "-tr" || name == "-ts" || name == "-bands") {
      // -merge writes vector output: the raster's options belong to no run of the pair.
      throw UsageError("-tile writes a tile product, not a dataset: " + state.output_option +
                       " is for a raster, which a whole run writes, or tile jobs in parts with -part (-merge "
                       "writes vector output)");
    }
    throw UsageError("-tile writes a tile product, not a dataset: give " + state.output_option + " to the -merge run");
  }
  // Which of the two a batch job meant is a guess: refuse the pair.
  if (!run.read.sql.empty() && !run.read.where.empty()) {
    throw UsageError("-sql and -where exclude each other: put the condition in the -sql statement");
  }
  if (!run.read.sql.empty() && !run.read.layers.empty()) {
    throw UsageError("-sql and -l exclude each other: the -sql statement names its tables");
  }
  if (state.tr || state.ts) {
    // A pixel size only makes sense for the lon/lat grid, so it implies it.
    if (state.raster_named && run.raster.layout == write::RasterOptions::Layout::qtm) {
      throw UsageError("-tr and -ts are for -raster lonlat: the QTM-coded raster's size follows the level");
    }
    if (run.kind == OutputKind::vector) throw UsageError("-tr and -ts are for raster output, not with -layers");
    run.raster.layout = write::RasterOptions::Layout::lonlat;
    run.kind = OutputKind::raster;
  }
}

// Whether the command line asks for an index of parts (-merge with -of VRT, or one .vrt name).
bool is_part_index(const VoronoiOptions& run, const std::vector<std::string>& positional) {
  if (run.merge.empty() || positional.empty()) return false;
  if (!run.format.empty()) return EQUAL(run.format.c_str(), "VRT");
  return positional.size() == 1 && EQUAL(CPLGetExtension(positional[0].c_str()), "vrt");
}

extern "C" void on_signal(int signal_number) { g_signal = signal_number; }

}  // namespace

Options parse_command_line(const std::vector<std::string>& args) {
  Options o;
  for (const std::string& arg : args) {
    if (arg == "--") break;
    const std::string name = option_name(arg);
    if (is_help(name)) {
      o.help = true;
      return o;
    }
    if (name == "-version") {
      o.version = true;
      return o;
    }
  }
  std::vector<std::string> positional;
  bool options_ended = false;
  ParseState state;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (options_ended || !looks_like_option(arg)) {
      positional.push_back(arg);
      continue;
    }
    if (arg == "--") {
      options_ended = true;
      continue;
    }
    const std::string name = option_name(arg);
    if (shapes_output(name) && state.output_option.empty()) state.output_option = arg;
    if (state.raster_option.empty() && (name == "-co" || name == "-ot" || name == "-raster" || name == "-tr" ||
                                        name == "-ts" || name == "-bands")) {
      state.raster_option = arg;
    }
    if (name == "-layers") state.layers_named = true;
    const OptionAt at{arg, name, args, i};
    if (!parse_reader_option(at, o.run.read) && !parse_labeller_option(at, o.run) && !parse_vector_option(at, o.run) &&
        !parse_raster_option(at, o.run, state) && !parse_run_option(at, o)) {
      throw UsageError("unknown option '" + arg + "'");
    }
  }
  check_option_combinations(o.run, state);
  if (is_part_index(o.run, positional)) {
    // -merge PARTS -of VRT index.vrt: the parts' index reads no source.
    if (positional.size() > 1) {
      throw UsageError("-merge of parts into an index (-of VRT) reads no source: give only the index's name, not '" +
                       positional[0] + "' and '" + positional[1] + "'");
    }
    o.destination = positional[0];
    return o;
  }
  if (positional.size() < 2) {
    throw UsageError(positional.empty() ? "SRC_DATASOURCE and DST_DATASOURCE are missing" : "DST_DATASOURCE is missing");
  }
  if (positional.size() > 2) throw UsageError("too many arguments: '" + positional[2] + "'");
  o.source = positional[0];
  o.destination = positional[1];
  return o;
}

void TermProgress::update(double fraction) {
  const int tick = std::max(0, std::min(40, static_cast<int>(fraction * 40.0)));
  if (tick < ticks_ && ticks_ >= 39) ticks_ = -1;  // a new run after a finished one
  if (tick <= ticks_) return;
  while (tick > ticks_) {
    ++ticks_;
    if (ticks_ % 4 == 0) {
      std::fprintf(out_, "%d", ticks_ / 4 * 10);
    } else {
      std::fputc('.', out_);
    }
  }
  if (ticks_ == 40) std::fputs(" - done.\n", out_);
  std::fflush(out_);
}

void TermProgress::break_line() {
  if (mid_line()) std::fputc('\n', out_);
}

void install_signal_handlers() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND;  // a second signal kills at once, as users expect of Ctrl-C
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  // Past a file size limit (ulimit -f) SIGXFSZ would kill us mid-write, leaving the temporary
  // directory behind; ignored, the write fails with EFBIG and the run cleans up like any failure.
  signal(SIGXFSZ, SIG_IGN);
}

int qtmvoronoi_main(int argc, char** argv) {
  // --help and --version before GDAL's processor, which answers --version with GDAL's own.
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--") == 0) break;
    const std::string name = option_name(argv[k]);
    if (is_help(name)) {
      std::fputs(kHelpText, stdout);
      return kExitOk;
    }
    if (name == "-version") {
      std::printf("qtmvoronoi %s (%s)\n", QTMV_VERSION_STRING, GDALVersionInfo("--version"));
      return kExitOk;
    }
  }
  auto usage_error = [](const std::string& message) {
    std::fprintf(stderr, "qtmvoronoi: %s\n%s", message.c_str(), kUsageText);
    return kExitUsage;
  };

  GDALAllRegister();
  char** args = argv;
  // --config KEY VALUE, --formats, --debug, --optfile, ...; returns below 1 when it answered
  // (--formats: 0) or failed (a missing value: -1, after its message).
  const int count = GDALGeneralCmdLineProcessor(argc, &args, 0);
  if (count < 1) return count == 0 ? kExitOk : usage_error("bad GDAL option");
  const std::vector<std::string> arguments(args + 1, args + count);
  CSLDestroy(args);

  Options options;
  try {
    options = parse_command_line(arguments);
  } catch (const UsageError& e) {
    return usage_error(e.what());
  }

  const bool show_progress = !options.quiet && (options.progress || isatty(STDERR_FILENO));
  TermProgress bar(stderr);
  // Informative lines wait while the bar runs; warnings break its line.
  std::vector<std::string> deferred;
  auto flush_deferred = [&] {
    for (const std::string& line : deferred) std::fprintf(stderr, "qtmvoronoi: %s\n", line.c_str());
    deferred.clear();
  };
  VoronoiOptions& run = options.run;
  // Trace lines may come from a labeller's worker thread: one line, or one bar update, at a time.
  std::mutex terminal;
  run.messages = [&](Severity severity, const std::string& message) {
    const std::lock_guard<std::mutex> lock(terminal);
    if (severity == Severity::info) {
      if (options.quiet) return;
      if (show_progress) {
        deferred.push_back(message);
        return;
      }
    }
    // Warnings, and the trace channel's lines (asked for by QTMV_TRACE, so printed under -q too), break the bar's line.
    bar.break_line();
    std::fprintf(stderr, "qtmvoronoi: %s%s\n", severity == Severity::warning ? "warning: " : "", message.c_str());
  };
  run.progress = [&](double fraction, const char*) {
    if (g_signal != 0) return false;
    const std::lock_guard<std::mutex> lock(terminal);
    if (show_progress) bar.update(fraction);
    return true;
  };

  // CUDA is to start only the devices asked for (the driver starts every visible one), and no
  // CUDA call has been made yet: the names stay the user's (common/visible_devices.hpp).
  restrict_visible_devices(run.device);
  install_signal_handlers();
  try {
    run_voronoi(options.source, options.destination, run);
  } catch (const Interrupted&) {
    bar.break_line();
    flush_deferred();
    const char* name = g_signal == SIGINT ? "SIGINT" : g_signal == SIGTERM ? "SIGTERM" : "a signal";
    std::fprintf(stderr, "qtmvoronoi: interrupted by %s: '%s' not written\n", name, options.destination.c_str());
    return kExitFailure;
  } catch (const std::exception& e) {
    bar.break_line();
    flush_deferred();
    std::fprintf(stderr, "qtmvoronoi: %s\n", e.what());
    return kExitFailure;
  }
  flush_deferred();
  return kExitOk;
}

}  // namespace qtmv::qtmvoronoi
