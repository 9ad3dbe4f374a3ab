// The labeller's run: input checks, device choice, the algorithm, tiling, and the hand-over to
// the stages (candidates.cpp, tree_build.cpp, cpu_painter.cpp, cuda/label_cuda.cu).
#include "label/labeller.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <future>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>

#include "common/device_spec.hpp"
#include "common/host_info.hpp"
#include "common/trace.hpp"
#include "grid/qtm_checks.hpp"
#include "label/cpu_painter.hpp"
#include "label/fixed_cover.hpp"
#include "label/label_cuda.hpp"
#include "label/label_engine.hpp"
#include "common/openmp_threads.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_node_rule.hpp"


namespace qtmv::label {

namespace {

constexpr std::uint64_t kMinTileCells = 4096;  // below this, tiling is pointless: refuse

bool is_unit(const Vec3& v) {
  const double n = grid::dot(v, v);
  return std::isfinite(n) && std::fabs(n - 1.0) < 1e-9;
}

void validate(const LabelInput& in, Rule rule) {
  grid::require_level(in.level);
  if (in.site_count <= 0) throw std::invalid_argument("there are no sites to label with");
  auto check_site = [&](std::int32_t site, const char* what) {
    if (site < 0 || site >= in.site_count) {
      throw std::invalid_argument(std::string(what) + " has site id " + std::to_string(site) +
                                  ", outside 0.." + std::to_string(in.site_count - 1));
    }
  };
  for (std::size_t k = 0; k < in.piece_count; ++k) {
    const SitePiece& p = in.pieces[k];
    check_site(p.site, "a site piece");
    if (!is_unit(p.a) || !is_unit(p.b)) {
      throw std::invalid_argument("site piece " + std::to_string(k) + " has an end that is not a unit vector");
    }
    if (grid::dot(p.a, p.b) < 0.0) {
      throw std::invalid_argument("site piece " + std::to_string(k) + " is longer than a quarter circle");
    }
  }
  for (std::size_t k = 0; k < in.site_cell_count; ++k) {
    check_site(in.site_cells[k].site, "a site cell");
    grid::require_code(in.site_cells[k].code, in.level);
  }
  for (std::size_t k = 0; k < in.fixed_cell_count; ++k) {
    check_site(in.fixed_cells[k].site, "a fixed cell");
    grid::require_code(in.fixed_cells[k].code, in.level);
  }
  for (std::size_t k = 0; k < in.fixed_node_count; ++k) {
    const FixedNode& n = in.fixed_nodes[k];
    check_site(n.site, "a fixed node");
    if (n.level < 0 || n.level > in.level) {
      throw std::invalid_argument("fixed node " + std::to_string(k) + " has level " + std::to_string(n.level) +
                                  ", outside 0.." + std::to_string(in.level));
    }
    grid::require_code(n.code, n.level);
  }
  const bool fixed = in.fixed_cell_count + in.fixed_node_count > 0;
  if (rule == Rule::exact && in.piece_count == 0 && !fixed) {
    throw std::invalid_argument("the exact rule needs site pieces (points or arcs) or fixed cells");
  }
  if (rule == Rule::cell && in.site_cell_count == 0 && !fixed) {
    throw std::invalid_argument("the cell rule needs site cells or fixed cells");
  }
}

}  // namespace

std::vector<DeviceChoice> choose_devices(const std::string& name) {
  const DeviceSpec spec = parse_device_spec(name);
  if (spec.kind == DeviceSpec::Kind::cpu) return {DeviceChoice{}};
  const int count = cuda::device_count();
  if (spec.kind == DeviceSpec::Kind::automatic) return {count > 0 ? DeviceChoice{true, 0} : DeviceChoice{}};
  if (count == 0) throw std::runtime_error("device '" + name + "' was asked for, but no usable CUDA GPU was found");
  std::vector<DeviceChoice> out;
  if (spec.all) {
    for (int d = 0; d < count; ++d) out.push_back({true, d});
    return out;
  }
  for (const int index : spec.indices) {
    if (index >= count) {
      throw std::runtime_error("device '" + name + "' was asked for, but there are only " + std::to_string(count) +
                               " CUDA device(s)");
    }
    out.push_back({true, index});
  }
  return out;
}

DeviceChoice choose_device(const std::string& name) { return choose_devices(name).front(); }

void check_label_input(const LabelInput& input, Rule rule) { validate(input, rule); }

// --- the run --------------------------------------------------------------------------------

MemoryEstimate estimate_output_memory(int level, const LabelOptions& options) {
  grid::require_level(level);
  MemoryEstimate e;
  e.cells = grid::cell_count(level);
  e.bytes_per_cell = sizeof(std::int32_t) + (options.want_distance ? sizeof(float) : 0) + (options.want_boundary ? 1 : 0);
  e.output_bytes = e.cells * e.bytes_per_cell;
  return e;
}

namespace {

/// The codes a run labels: options.range, or the whole level when it is empty. Throws
/// std::invalid_argument unless they are whole rows of the level.
grid::CodeRange range_of(const LabelOptions& options, int level) {
  const grid::CodeRange range = options.range.end == 0 ? grid::whole_level(level) : options.range;
  if (!grid::is_rows(range, level)) {
    throw std::invalid_argument("codes " + std::to_string(range.first) + " to " + std::to_string(range.end) +
                                " are not whole rows of level " + std::to_string(level));
  }
  return range;
}

/// The host's buffers for one tile of outputs.
struct HostTile {
  std::uint64_t cells;
  std::int32_t* site;
  float* metres;           // null: no distances
  std::uint8_t* boundary;  // null: no flags
};

/// label_cells on a GPU: device tiles as large as its memory allows (smaller ones when an
/// allocation fails), each copied to the host tile by tile and handed to the sink. `done` counts
/// the cells handed over, for the CPU to go on from when the GPU runs out of memory mid-run.
/// With `outline`, the tiles' outline cells are selected on the device and appended to it
/// instead (the host tile is not used).
void label_on_gpu(cuda::Labeller& gpu, int device, int level, grid::CodeRange range, const LabelOptions& options,
                  const MemoryEstimate& need, const HostTile& host, const std::function<void(const LabelTile&)>& sink,
                  LabelStats& stats, std::uint64_t& done, OutlineCells* outline) {
  const std::uint64_t total = range.size();
  const cuda::DeviceInfo info = cuda::device_info(device);
  const std::uint64_t device_limit =
      options.memory_limit_bytes ? options.memory_limit_bytes : static_cast<std::uint64_t>(info.free_bytes * 0.8);
  // The outline selection's buffers (kOutlineSelectBytesPerCell a cell of a chunk, which is at
  // most kOutlineChunkCells and at most a tile) come out of the same memory.
  const std::uint64_t select = outline ? cuda::kOutlineSelectBytesPerCell : 0;
  std::uint64_t device_tile = std::min<std::uint64_t>(total, device_limit / (need.bytes_per_cell + select));
  if (outline && device_tile > cuda::kOutlineChunkCells) {
    device_tile = std::min<std::uint64_t>(
        total, (device_limit - cuda::kOutlineChunkCells * cuda::kOutlineSelectBytesPerCell) / need.bytes_per_cell);
  }
  if (device_tile < std::min<std::uint64_t>(total, kMinTileCells)) {
    throw std::runtime_error("level " + std::to_string(level) + " needs " + format_gib(double(need.output_bytes)) +
                             " of outputs on the GPU; not even a tile of 4096 cells fits in the " +
                             format_gib(double(device_limit)) + " available");
  }
  const bool trace = trace_enabled(TraceStage::label);
  const double reserve_start = now_seconds();
  for (;;) {
    try {
      gpu.reserve(device_tile, options.want_distance, options.want_boundary);
      break;
    } catch (const cuda::OutOfMemory&) {
      if (device_tile <= kMinTileCells) throw;
      device_tile = std::max<std::uint64_t>(kMinTileCells, device_tile / 4);
      tell(options.messages, Severity::warning,
           "the GPU could not hold the outputs' tile; trying tiles of " + std::to_string(device_tile) + " cells");
    }
  }
  if (device_tile < total) {
    tell(options.messages, Severity::info,
         "level " + std::to_string(level) + " outputs take " + format_gib(double(need.output_bytes)) +
             "; labelling in tiles of " + std::to_string(device_tile) + " cells");
  }
  stats.device_bytes = gpu.device_bytes();
  if (trace) {
    trace_printf(TraceStage::label, "device buffers of %llu cells: %.3f s", static_cast<unsigned long long>(device_tile),
                 now_seconds() - reserve_start);
  }
  for (std::uint64_t first = done; first < range.end; first += device_tile) {
    const std::uint64_t count = std::min(device_tile, range.end - first);
    const double tile_start = now_seconds();
    stats.label_seconds += gpu.run(first, count, options.want_distance, options.want_boundary) / 1e3;
    const double run_end = now_seconds();
    ++stats.tiles;
    if (outline) {
      stats.copy_seconds += gpu.select_outline(first, count, outline) / 1e3;
      done = first + count;
      // Room for the tiles to come at this tile's rate, so that the list grows once.
      if (done < range.end && outline->capacity() < outline->size() * 2) {
        const double rate = static_cast<double>(outline->size()) / static_cast<double>(done - range.first);
        outline->reserve(outline->size() + static_cast<std::size_t>(rate * 1.1 * static_cast<double>(range.end - done)));
      }
      if (trace) {
        trace_printf(TraceStage::label, "tile of %llu cells: run %.3f s, outline selection %.3f s (%zu outline cells so far)",
                     static_cast<unsigned long long>(count), run_end - tile_start, now_seconds() - run_end, outline->size());
      }
    }
    for (std::uint64_t offset = 0; !outline && offset < count; offset += host.cells) {
      const std::uint64_t part = std::min(host.cells, count - offset);
      stats.copy_seconds += gpu.download(offset, part, host.site, host.metres, host.boundary) / 1e3;
      sink({first + offset, part, host.site, host.metres, host.boundary});
      done = first + offset + part;
    }
    report_progress(options.progress, double(first + count - range.first) / double(total), "label");
  }
}

}  // namespace

namespace {

/// Whether the CPU's tree pass (cpu_tree_outlines) beats dense tiles: it labels the cells of the
/// list leaves and about half as many again around them, where dense tiles label every cell once
/// (uniform leaves' cells almost for free) and then scan them all. Where list leaves hold more than
/// a third of the cells (polygons' coasts at coarse levels: 62% of Natural Earth's 110m countries
/// at level 10, where the tree pass took 1.7x as long), the dense tiles win.
bool outline_pass_pays(const Tree& tree) {
  std::uint64_t list_cells = 0;
  for (const TreeLeaf& leaf : tree.leaves) {
    if (tree.nodes[static_cast<std::size_t>(leaf.node)].count != kUniform) {
      list_cells += std::uint64_t{1} << (2 * (tree.level - leaf.level));
    }
  }
  // A tree built for a range (a tile job's) has list leaves only in and around it.
  const std::uint64_t cells = tree.labelled_cells();
  trace_printf(TraceStage::label, "list-leaf cells %llu of %llu", static_cast<unsigned long long>(list_cells),
               static_cast<unsigned long long>(cells));
  return list_cells * 3 <= cells;
}

/// label_cells, or with `outline` label_outlines' pass (no sink then).
LabelStats run_labelling(const LabelInput& given, const LabelOptions& options,
                         const std::function<void(const LabelTile&)>& sink, OutlineCells* outline) {
  validate(given, options.rule);
  const int threads = thread_count(options.threads);
  const DeviceChoice device = choose_device(options.device);
  const grid::CodeRange range = range_of(options, given.level);
  LabelStats stats;
  auto say = [&](const std::string& message) { tell(options.messages, Severity::info, message); };
  auto progress = [&](double fraction, const char* stage) { report_progress(options.progress, fraction, stage); };
  if (device.cuda) {
    const cuda::DeviceInfo info = cuda::device_info(device.index);
    stats.device = "cuda:" + std::to_string(device.index) + " (" + info.name + ")";
  } else {
    stats.device = "cpu (" + std::to_string(threads) + " threads)";
  }

  const double t0 = now_seconds();
  progress(0.0, "prepare");
  // Brute force tests every claimed cell's centre; the tree only the fixed cells finer than its
  // list level (the coarser fixed nodes are its cover's uniform leaves at once).
  const double brute_candidates =
      static_cast<double>((options.rule == Rule::exact ? given.piece_count : given.site_cell_count) +
                          given.fixed_cell_count + fixed_node_cells(given));
  stats.algorithm = options.algorithm;
  if (stats.algorithm == Algorithm::automatic) {
    const double work = static_cast<double>(grid::cell_count(given.level)) * brute_candidates;
    stats.algorithm = device.cuda && work <= kBruteWorkLimit ? Algorithm::brute : Algorithm::hier;
  }
  const bool hier = stats.algorithm == Algorithm::hier;
  // The host's tree: the outline pass needs only a coarse jump table; the dense paths and a GPU
  // given the host's tree fill the full one (fill_jump_table) when they run.
  const JumpTable jump_table = outline ? JumpTable::outline : JumpTable::full;
  // Fixed nodes: the tree takes them as its cover (a node of its list level or above is a
  // uniform leaf at once) and fixed points only where a list leaf may meet claimed cells; brute
  // force takes every claimed cell as a fixed point.
  const PreparedInput prepared = prepare_input(given, hier);
  const LabelInput& input = prepared.input;
  const CoverView cover_view = prepared.cover.view();
  // The host's candidates, made when the host needs them: the exact rule's device build makes
  // its own from the input.
  std::vector<Piece> candidates;
  bool candidates_made = false;
  auto host_candidates = [&]() -> const std::vector<Piece>& {
    if (!candidates_made) candidates = make_candidates(input, options.rule, threads);
    candidates_made = true;
    return candidates;
  };
  say("labelling on " + stats.device + (hier ? ", pruned tree (hier)" : ", brute force"));
  // On a GPU the tree is built there (cuda::Labeller's device constructor), inside prepare.
  const bool device_tree = hier && device.cuda && options.tree_on_device;
  std::unique_ptr<cuda::Labeller> gpu_built;
  Tree tree;
  // A GPU that runs out of memory hands the rest of the work to the CPU, with a warning.
  bool on_gpu = device.cuda;
  auto leave_gpu = [&](const cuda::OutOfMemory& e, std::uint64_t from) {
    tell(options.messages, Severity::warning,
         "the GPU ran out of memory (" + std::string(e.what()) + "); labelling " +
             (from == range.first ? std::string("on the CPU") : "cells " + std::to_string(from) + " onwards on the CPU") +
             " instead");
    on_gpu = false;
    gpu_built.reset();
    stats.device += ", then cpu (" + std::to_string(threads) + " threads)";
  };
  if (device_tree) {
    try {
      gpu_built = options.rule == Rule::exact
                      ? std::make_unique<cuda::Labeller>(device.index, input, options.want_distance, threads,
                                                         &cover_view)
                      : std::make_unique<cuda::Labeller>(device.index, host_candidates(), input.level,
                                                         options.want_distance, threads, &cover_view);
    } catch (const std::length_error&) {
      // Too large for the device build's 32-bit work counts: the host builds it (below).
      gpu_built.reset();
    } catch (const cuda::OutOfMemory& e) {
      leave_gpu(e, range.first);
    }
  }
  if (gpu_built) {
    const cuda::TreeInfo info = gpu_built->tree_info();
    stats.tree_nodes = info.nodes;
    stats.tree_list_entries = info.list_entries;
    stats.mean_candidates = info.mean_candidates;
  } else if (hier) {
    // Progress after each level of the build, so that a caller can stop a long build.
    tree = build_tree(host_candidates(), input.level, options.want_distance, threads,
                      [&](double fraction) { progress(fraction, "prepare"); }, &cover_view, jump_table, range);
    stats.tree_nodes = tree.nodes.size();
    stats.tree_list_entries = tree.lists.size();
    stats.mean_candidates = tree.mean_candidates;
  } else {
    stats.mean_candidates = options.rule == Rule::exact ? static_cast<double>(input.piece_count + input.fixed_cell_count)
                                                        : static_cast<double>(host_candidates().size());
  }
  stats.prepare_seconds = now_seconds() - t0;

  const MemoryEstimate need = estimate_output_memory(input.level, options);
  const std::uint64_t total = range.size();
  // Host tiles are bounded so that a whole-globe run does not double the caller's memory.
  const std::uint64_t host_limit = options.memory_limit_bytes ? options.memory_limit_bytes : host_ram_bytes() / 4;
  std::uint64_t host_tile = std::min<std::uint64_t>(total, std::max<std::uint64_t>(1, host_limit / need.bytes_per_cell));
  host_tile = std::min<std::uint64_t>(host_tile, std::uint64_t{1} << 28);
  if (host_tile < std::min<std::uint64_t>(total, kMinTileCells)) {
    throw std::runtime_error("level " + std::to_string(input.level) + " needs " + format_gib(double(need.output_bytes)) +
                             " of outputs; not even a tile of 4096 cells fits in the " + format_gib(double(host_limit)) +
                             " allowed");
  }
  // The outline pass takes a host tile only for the CPU's dense tiles (brute force).
  // Not zeroed (a tile is up to 2^28 cells): each tile's labellers write every cell of it.
  DefaultInitVector<std::int32_t> site(outline ? 0 : host_tile);
  DefaultInitVector<float> metres(options.want_distance && !outline ? host_tile : 0);
  DefaultInitVector<std::uint8_t> boundary(options.want_boundary && !outline ? host_tile : 0);
  float* metres_ptr = metres.empty() ? nullptr : metres.data();
  std::uint8_t* boundary_ptr = boundary.empty() ? nullptr : boundary.data();

  std::uint64_t done = range.first;  // cells up to here handed to the sink
  if (on_gpu) {
    try {
      if (!gpu_built) {
        if (hier) fill_jump_table(tree, tree_jump_level(input.level), threads);
        gpu_built =
            std::make_unique<cuda::Labeller>(device.index, host_candidates(), hier ? &tree : nullptr, input.level);
      }
      const HostTile host{host_tile, site.data(), metres_ptr, boundary_ptr};
      const double gpu_start = now_seconds();
      label_on_gpu(*gpu_built, device.index, input.level, range, options, need, host, sink, stats, done, outline);
      trace_printf(TraceStage::label, "%s: %zu tiles, kernels %.3f s, outline selection and copies %.3f s, wall %.3f s",
                   stats.device.c_str(), stats.tiles, stats.label_seconds, stats.copy_seconds, now_seconds() - gpu_start);
      gpu_built.reset();
      cuda::release_cached_memory(device.index);
      return stats;
    } catch (const cuda::OutOfMemory& e) {
      leave_gpu(e, done);
    }
    if (hier && tree.nodes.empty()) {
      tree = build_tree(host_candidates(), input.level, options.want_distance, threads, {}, &cover_view, jump_table,
                        range);
    }
  }
  if (outline && hier && outline_pass_pays(tree)) {
    const TreeView tv = tree.view(host_candidates().data());
    // Only the leaves that can touch an outline are visited (after a GPU that ran out of memory,
    // those of the cells it had not done).
    const double start = now_seconds();
    const OutlineCells cpu = cpu_tree_outlines(tree, tv, threads, {done, range.end},
                                                           [&](double fraction) { progress(fraction, "label"); });
    outline->insert(outline->end(), cpu.begin(), cpu.end());
    stats.label_seconds += now_seconds() - start;
    ++stats.tiles;
    progress(1.0, "label");
    return stats;
  }
  if (hier) fill_jump_table(tree, tree_jump_level(input.level), threads);
  const TreeView tv = tree.view(host_candidates().data());
  if (outline) {  // the CPU's dense tiles, compacted as they come
    site.resize(host_tile);
    boundary.resize(host_tile);
    boundary_ptr = boundary.data();
  }
  for (std::uint64_t first = done; first < range.end; first += host_tile) {
    const std::uint64_t count = std::min(host_tile, range.end - first);
    const double start = now_seconds();
    if (hier) {
      cpu_tree_range(tree, tv, first, count, site.data(), metres_ptr, boundary_ptr, threads);
    } else {
      cpu_brute_range(candidates, input.level, first, count, site.data(), metres_ptr, boundary_ptr, threads);
    }
    stats.label_seconds += now_seconds() - start;
    ++stats.tiles;
    if (outline) {
      append_outline_cells(input.level, first, count, site.data(), boundary_ptr, threads, outline);
    } else {
      sink({first, count, site.data(), metres_ptr, boundary_ptr});
    }
    progress(double(first + count - range.first) / double(total), "label");
  }
  return stats;
}

}  // namespace

LabelStats label_cells(const LabelInput& input, const LabelOptions& options,
                       const std::function<void(const LabelTile&)>& sink) {
  return run_labelling(input, options, sink, nullptr);
}

LabelStats label_outlines(const LabelInput& input, const LabelOptions& options, Outlines* out) {
  const std::vector<DeviceChoice> devices = choose_devices(options.device);
  if (devices.size() > 1) {
    std::vector<std::string> names;
    for (const DeviceChoice& d : devices) names.push_back("cuda:" + std::to_string(d.index));
    return label_outlines_on(input, options, names, out);
  }
  LabelOptions outline_options = options;
  outline_options.want_distance = false;
  outline_options.want_boundary = true;
  Outlines result;
  result.level = input.level;
  result.site_count = input.site_count;
  result.range = range_of(options, input.level);
  const LabelStats stats = run_labelling(input, outline_options, {}, &result.cells);
  result.cells_per_site = count_cells_per_site(result.cells, input.level, input.site_count, result.range.end);
  *out = std::move(result);
  return stats;
}

LabelStats label_outlines_on(const LabelInput& input, const LabelOptions& options,
                             const std::vector<std::string>& devices, Outlines* out) {
  if (devices.empty()) throw std::invalid_argument("label_outlines_on: no device");
  grid::require_level(input.level);
  const grid::CodeRange range = range_of(options, input.level);
  const std::vector<grid::CodeRange> parts = grid::split_in_rows(range, static_cast<int>(devices.size()), input.level);
  const std::size_t n = parts.size();
  std::vector<Outlines> products(n);
  std::vector<LabelStats> stats(n);
  // Each part reports its fraction here; the calling thread passes their mean on, and a stop
  // asked for there stops every part at its next report.
  std::vector<std::atomic<double>> fraction(n);
  std::atomic<bool> stop{false};
  // The parts' messages wait here for the calling thread, which passes them on.
  std::mutex message_lock;
  std::vector<std::pair<Severity, std::string>> pending;
  const auto pass_messages_on = [&] {
    std::vector<std::pair<Severity, std::string>> now;
    {
      const std::lock_guard<std::mutex> hold(message_lock);
      now.swap(pending);
    }
    for (const auto& [severity, message] : now) tell(options.messages, severity, message);
  };
  report_progress(options.progress, 0.0, "label");
  std::vector<std::future<void>> runs;
  for (std::size_t k = 0; k < n; ++k) {
    fraction[k] = 0.0;
    runs.push_back(std::async(std::launch::async, [&, k] {
      LabelOptions part = options;
      part.device = devices[k];
      part.range = parts[k];
      part.progress = [&, k](double f, const char* stage) {
        if (std::strcmp(stage, "label") == 0) fraction[k] = f;  // its labelling, after its tree's build
        return !stop.load();
      };
      part.messages = [&, k](Severity severity, const std::string& message) {
        const std::lock_guard<std::mutex> hold(message_lock);
        pending.emplace_back(severity, devices[k] + ": " + message);
      };
      stats[k] = label_outlines(input, part, &products[k]);
    }));
  }
  // A part's failure stops the others; it is the one reported, not the others' Interrupted.
  std::exception_ptr failure;
  bool interrupted = false;
  for (std::size_t k = 0; k < n; ++k) {
    while (runs[k].wait_for(std::chrono::milliseconds(100)) != std::future_status::ready) {
      pass_messages_on();
      double sum = 0;
      for (const auto& f : fraction) sum += f.load();
      if (options.progress && !stop.load() && !options.progress(sum / double(n), "label")) stop = true;
    }
    try {
      runs[k].get();
    } catch (const Interrupted&) {
      interrupted = true;
    } catch (...) {
      if (!failure) failure = std::current_exception();
      stop = true;
    }
  }
  pass_messages_on();
  if (failure) std::rethrow_exception(failure);
  if (stop || interrupted) throw Interrupted();

  // The parts' products, joined in code order; their stats as one run's.
  Outlines joined;
  joined.level = input.level;
  joined.site_count = input.site_count;
  joined.range = range;
  joined.cells_per_site.assign(static_cast<std::size_t>(input.site_count), 0);
  std::size_t cells = 0;
  for (const Outlines& p : products) cells += p.cells.size();
  // One allocation, filled on all cores (first touch included): gigabytes at high levels.
  joined.cells.resize(cells);
  std::size_t at = 0;
  for (Outlines& p : products) {
    constexpr std::int64_t kBlock = std::int64_t{1} << 20;
    const auto blocks = static_cast<std::int64_t>((p.cells.size() + kBlock - 1) / kBlock);
#pragma omp parallel for schedule(static) num_threads(thread_count(options.threads))
    for (std::int64_t b = 0; b < blocks; ++b) {
      const std::size_t first = static_cast<std::size_t>(b * kBlock);
      const std::size_t size = std::min<std::size_t>(kBlock, p.cells.size() - first);
      std::memcpy(joined.cells.data() + at + first, p.cells.data() + first, size * sizeof(OutlineCell));
    }
    at += p.cells.size();
    OutlineCells().swap(p.cells);
  }
  LabelStats all = stats.front();
  all.device.clear();
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t s = 0; s < joined.cells_per_site.size(); ++s) joined.cells_per_site[s] += products[k].cells_per_site[s];
    all.device += (k ? ", " : "") + stats[k].device;
    all.prepare_seconds = std::max(all.prepare_seconds, stats[k].prepare_seconds);
    all.label_seconds = std::max(all.label_seconds, stats[k].label_seconds);
    all.copy_seconds = std::max(all.copy_seconds, stats[k].copy_seconds);
    all.device_bytes = std::max(all.device_bytes, stats[k].device_bytes);
    if (k > 0) all.tiles += stats[k].tiles;
  }
  *out = std::move(joined);
  return all;
}

LabelResult label_all(const LabelInput& input, const LabelOptions& options) {
  grid::require_level(input.level);
  const MemoryEstimate need = estimate_output_memory(input.level, options);
  const std::uint64_t ram = host_ram_bytes();
  if (need.output_bytes > ram / 2) {
    throw std::runtime_error("level " + std::to_string(input.level) + " needs " + format_gib(double(need.output_bytes)) +
                             " for its dense outputs, more than half of this host's " + format_gib(double(ram)) +
                             "; use label_cells() to stream tiles instead");
  }
  return label_dense(input, options);
}

LabelResult label_dense(const LabelInput& input, const LabelOptions& options) {
  const MemoryEstimate need = estimate_output_memory(input.level, options);
  LabelResult result;
  result.site.resize(need.cells);
  if (options.want_distance) result.distance_m.resize(need.cells);
  if (options.want_boundary) result.boundary.resize(need.cells);
  result.stats = label_cells(input, options, [&](const LabelTile& tile) {
    std::memcpy(result.site.data() + tile.first, tile.site, tile.count * sizeof(std::int32_t));
    if (tile.distance_m) std::memcpy(result.distance_m.data() + tile.first, tile.distance_m, tile.count * sizeof(float));
    if (tile.boundary) std::memcpy(result.boundary.data() + tile.first, tile.boundary, tile.count);
  });
  return result;
}

int cuda_device_count() { return cuda::device_count(); }

}  // namespace qtmv::label
