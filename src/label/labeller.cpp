// The labeller's run: input checks, device choice, the algorithm, tiling, and the hand-over to
// the stages (candidates.cpp, tree_build.cpp, cpu_painter.cpp; on a GPU, cuda/label_cuda.cu and
// the stages' .cu files beside it).
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
#include "common/visible_devices.hpp"
#include "common/trace.hpp"
#include "grid/qtm_checks.hpp"
#include "label/cpu_painter.hpp"
#include "label/fixed_cover.hpp"
#include "label/outline_join.hpp"
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
  if (const int missing = first_missing_device(spec, count); missing >= 0) {
    throw std::runtime_error("device '" + name + "' was asked for, but " +
                             (visible_devices().restricted ? "this host has no CUDA device cuda:" + std::to_string(missing)
                                                           : "there are only " + std::to_string(count) + " CUDA device(s)"));
  }
  std::vector<DeviceChoice> out;
  if (spec.all) {
    for (int d = 0; d < count; ++d) out.push_back({true, d});
    return out;
  }
  // The user's cuda:N, as this process's CUDA ordinal (common/visible_devices.hpp).
  for (const int index : spec.indices) out.push_back({true, cuda_ordinal(index)});
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

/// Room in *outline for the rest of a range (outline_room_for_rest), so that the list grows
/// once, not by doubling: each growth copies all it holds, twice its memory for the while.
void reserve_for_rest(OutlineCells* outline, std::uint64_t cells_done, std::uint64_t cells_left) {
  if (cells_left == 0 || cells_done == 0 || outline->capacity() >= outline->size() * 2) return;
  grow_outline_cells(outline, outline->size() + outline_room_for_rest(outline->size(), cells_done, cells_left),
                     thread_count(0));
}

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
      stats.copy_seconds += gpu.select_outline(first, count, outline, range.end - (first + count)) / 1e3;
      done = first + count;  // select_outline gave the list room for the rest
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

/// One run of label_cells, or with `outline` of label_outlines' pass (no sink then), in named
/// steps: the algorithm, the tree (on the GPU or the host), the host's tile, then the labelling
/// on the GPU, or on the CPU by the outline pass or in dense tiles.
class LabellingRun {
 public:
  /// `given_back` (may be null): where a GPU's memory is given back on a thread of its own, for the
  /// caller to wait for (its seconds) while it goes on; null: given back before run() returns.
  LabellingRun(const LabelOptions& options, const std::function<void(const LabelTile&)>& sink, OutlineCells* outline,
               std::future<double>* given_back = nullptr)
      : options_(options), sink_(sink), outline_(outline), given_back_(given_back) {}

  LabelStats run(const LabelInput& given) {
    validate(given, options_.rule);
    threads_ = thread_count(options_.threads);
    device_ = choose_device(options_.device);
    range_ = range_of(options_, given.level);
    on_gpu_ = device_.cuda;
    if (device_.cuda) {
      const cuda::DeviceInfo info = cuda::device_info(device_.index);
      stats_.device = cuda_device_name(device_.index) + " (" + info.name + ")";
    } else {
      stats_.device = "cpu (" + std::to_string(threads_) + " threads)";
    }

    const double t0 = now_seconds();
    progress(0.0, "prepare");
    choose_algorithm(given);
    // Fixed nodes: the tree takes them as its cover (a node of its list level or above is a
    // uniform leaf at once) and fixed points only where a list leaf may meet claimed cells; brute
    // force takes every claimed cell as a fixed point.
    prepared_ = prepare_input(given, hier_);
    cover_view_ = prepared_.cover.view();
    say("labelling on " + stats_.device + (hier_ ? ", pruned tree (hier)" : ", brute force"));
    prepare_tree();
    stats_.prepare_seconds = now_seconds() - t0;

    HostBuffers host = host_buffers();
    std::uint64_t done = range_.first;  // cells up to here handed to the sink
    if (on_gpu_ && label_on_device(host, done)) return stats_;
    if (outline_ && hier_ && outline_pass_pays(tree_)) {
      outline_pass(done);
    } else {
      label_dense_tiles(host, done);
    }
    return stats_;
  }

 private:
  /// The host's buffers for one tile of outputs (empty where the run does not write them).
  struct HostBuffers {
    std::uint64_t cells = 0;  ///< of a tile
    DefaultInitVector<std::int32_t> site;
    DefaultInitVector<float> metres;
    DefaultInitVector<std::uint8_t> boundary;
    HostTile tile() {
      return {cells, site.data(), metres.empty() ? nullptr : metres.data(), boundary.empty() ? nullptr : boundary.data()};
    }
  };

  const LabelInput& input() const { return prepared_.input; }
  void say(const std::string& message) const { tell(options_.messages, Severity::info, message); }
  void progress(double fraction, const char* stage) const { report_progress(options_.progress, fraction, stage); }
  /// The host's tree: the outline pass needs only a coarse jump table; the dense paths and a GPU
  /// given the host's tree fill the full one (fill_jump_table) when they run.
  JumpTable jump_table() const { return outline_ ? JumpTable::outline : JumpTable::full; }

  /// The host's candidates, made when the host needs them: the exact rule's device build makes
  /// its own from the input.
  const std::vector<Piece>& host_candidates() {
    if (!candidates_made_) candidates_ = make_candidates(input(), options_.rule, threads_);
    candidates_made_ = true;
    return candidates_;
  }

  /// options.algorithm, with `automatic` settled.
  void choose_algorithm(const LabelInput& given) {
    // Brute force tests every claimed cell's centre; the tree only the fixed cells finer than its
    // list level (the coarser fixed nodes are its cover's uniform leaves at once).
    const double brute_candidates =
        static_cast<double>((options_.rule == Rule::exact ? given.piece_count : given.site_cell_count) +
                            given.fixed_cell_count + fixed_node_cells(given));
    stats_.algorithm = options_.algorithm;
    if (stats_.algorithm == Algorithm::automatic) {
      const double work = static_cast<double>(grid::cell_count(given.level)) * brute_candidates;
      stats_.algorithm = device_.cuda && work <= kBruteWorkLimit ? Algorithm::brute : Algorithm::hier;
    }
    hier_ = stats_.algorithm == Algorithm::hier;
  }

  /// A GPU that runs out of memory hands the rest of the work to the CPU, with a warning.
  void leave_gpu(const cuda::OutOfMemory& e, std::uint64_t from) {
    tell(options_.messages, Severity::warning,
         "the GPU ran out of memory (" + std::string(e.what()) + "); labelling " +
             (from == range_.first ? std::string("on the CPU") : "cells " + std::to_string(from) + " onwards on the CPU") +
             " instead");
    on_gpu_ = false;
    gpu_.reset();
    stats_.device += ", then cpu (" + std::to_string(threads_) + " threads)";
  }

  /// The tree of a hier run, on the GPU (cuda::Labeller's device constructor) or on the host, and
  /// the stats of the candidates a cell tests.
  void prepare_tree() {
    const bool device_tree = hier_ && device_.cuda && options_.tree_on_device;
    if (device_tree) {
      try {
        gpu_ = options_.rule == Rule::exact
                   ? std::make_unique<cuda::Labeller>(device_.index, input(), options_.want_distance, threads_,
                                                      &cover_view_)
                   : std::make_unique<cuda::Labeller>(device_.index, host_candidates(), input().level,
                                                      options_.want_distance, threads_, &cover_view_);
      } catch (const std::length_error&) {
        // Too large for the device build's 32-bit work counts: the host builds it (below).
        gpu_.reset();
      } catch (const cuda::OutOfMemory& e) {
        leave_gpu(e, range_.first);
      }
    }
    if (gpu_) {
      const cuda::TreeInfo info = gpu_->tree_info();
      stats_.tree_nodes = info.nodes;
      stats_.tree_list_entries = info.list_entries;
      stats_.mean_candidates = info.mean_candidates;
    } else if (hier_) {
      // Progress after each level of the build, so that a caller can stop a long build.
      tree_ = build_tree(host_candidates(), input().level, options_.want_distance, threads_,
                         [&](double fraction) { progress(fraction, "prepare"); }, &cover_view_, jump_table(), range_);
      stats_.tree_nodes = tree_.nodes.size();
      stats_.tree_list_entries = tree_.lists.size();
      stats_.mean_candidates = tree_.mean_candidates;
    } else {
      stats_.mean_candidates = options_.rule == Rule::exact
                                   ? static_cast<double>(input().piece_count + input().fixed_cell_count)
                                   : static_cast<double>(host_candidates().size());
    }
  }

  /// The host's tile: bounded so that a whole-globe run does not double the caller's memory. The
  /// outline pass takes one only for the CPU's dense tiles (then allocated by label_dense_tiles).
  HostBuffers host_buffers() {
    need_ = estimate_output_memory(input().level, options_);
    const std::uint64_t total = range_.size();
    const std::uint64_t host_limit = options_.memory_limit_bytes ? options_.memory_limit_bytes : host_ram_bytes() / 4;
    std::uint64_t host_tile = std::min<std::uint64_t>(total, std::max<std::uint64_t>(1, host_limit / need_.bytes_per_cell));
    host_tile = std::min<std::uint64_t>(host_tile, std::uint64_t{1} << 28);
    if (host_tile < std::min<std::uint64_t>(total, kMinTileCells)) {
      throw std::runtime_error("level " + std::to_string(input().level) + " needs " +
                               format_gib(double(need_.output_bytes)) + " of outputs; not even a tile of 4096 cells fits in the " +
                               format_gib(double(host_limit)) + " allowed");
    }
    // Not zeroed (a tile is up to 2^28 cells): each tile's labellers write every cell of it.
    HostBuffers host;
    host.cells = host_tile;
    host.site.resize(outline_ ? 0 : host_tile);
    host.metres.resize(options_.want_distance && !outline_ ? host_tile : 0);
    host.boundary.resize(options_.want_boundary && !outline_ ? host_tile : 0);
    return host;
  }

  /// Labels the range on the GPU from `done` on; true when it is done. When the GPU runs out of
  /// memory, `done` is where the CPU goes on from, and a hier run's tree is built on the host.
  bool label_on_device(HostBuffers& host, std::uint64_t& done) {
    try {
      if (!gpu_) {
        if (hier_) fill_jump_table(tree_, tree_jump_level(input().level), threads_);
        gpu_ = std::make_unique<cuda::Labeller>(device_.index, host_candidates(), hier_ ? &tree_ : nullptr,
                                                input().level);
      }
      const double gpu_start = now_seconds();
      label_on_gpu(*gpu_, device_.index, input().level, range_, options_, need_, host.tile(), sink_, stats_, done,
                   outline_);
      trace_printf(TraceStage::label, "%s: %zu tiles, kernels %.3f s, outline selection and copies %.3f s, wall %.3f s",
                   stats_.device.c_str(), stats_.tiles, stats_.label_seconds, stats_.copy_seconds,
                   now_seconds() - gpu_start);
      auto give_back = [gpu = std::move(gpu_), index = device_.index]() mutable {
        const double free_start = now_seconds();
        gpu.reset();
        cuda::release_cached_memory(index);
        return now_seconds() - free_start;
      };
      if (given_back_) {
        *given_back_ = std::async(std::launch::async, std::move(give_back));
      } else {
        trace_printf(TraceStage::label, "%s: device memory given back in %.3f s", stats_.device.c_str(), give_back());
      }
      return true;
    } catch (const cuda::OutOfMemory& e) {
      leave_gpu(e, done);
    }
    if (hier_ && tree_.nodes.empty()) {
      tree_ = build_tree(host_candidates(), input().level, options_.want_distance, threads_, {}, &cover_view_,
                         jump_table(), range_);
    }
    return false;
  }

  /// The CPU's tree pass (cpu_tree_outlines) from `done` on.
  void outline_pass(std::uint64_t done) {
    const TreeView tv = tree_.view(host_candidates().data());
    // Only the leaves that can touch an outline are visited (after a GPU that ran out of memory,
    // those of the cells it had not done).
    const double start = now_seconds();
    const grid::CodeRange rest{done, range_.end};
    std::vector<OutlineCells> parts =
        cpu_tree_outline_parts(tree_, tv, threads_, rest, [&](double fraction) { progress(fraction, "label"); });
    // The tree and its candidates are done with: freed before the threads' lists are joined.
    tree_ = Tree{};
    std::vector<Piece>().swap(candidates_);
    OutlineCells cpu = join_outline_parts(parts, input().level, rest, threads_);
    // Taken over where nothing came before it (no second copy of gigabytes).
    if (outline_->empty()) {
      outline_->swap(cpu);
    } else {
      outline_->insert(outline_->end(), cpu.begin(), cpu.end());
    }
    stats_.label_seconds += now_seconds() - start;
    ++stats_.tiles;
    progress(1.0, "label");
  }

  /// The CPU's dense tiles from `done` on, by the tree or by brute force: handed to the sink, or
  /// compacted into the outline cells as they come.
  void label_dense_tiles(HostBuffers& host, std::uint64_t done) {
    const int level = input().level;
    if (hier_) fill_jump_table(tree_, tree_jump_level(level), threads_);
    // Brute force needs the candidates alone; the tree a view of itself over them.
    const std::vector<Piece>& candidates = host_candidates();
    const TreeView tv = hier_ ? tree_.view(candidates.data()) : TreeView{};
    if (outline_) {
      host.site.resize(host.cells);
      host.boundary.resize(host.cells);
    }
    const HostTile tile = host.tile();
    const std::uint64_t total = range_.size();
    for (std::uint64_t first = done; first < range_.end; first += host.cells) {
      const std::uint64_t count = std::min(host.cells, range_.end - first);
      const double start = now_seconds();
      if (hier_) {
        cpu_tree_range(tree_, tv, first, count, tile.site, tile.metres, tile.boundary, threads_);
      } else {
        cpu_brute_range(candidates, level, first, count, tile.site, tile.metres, tile.boundary, threads_);
      }
      stats_.label_seconds += now_seconds() - start;
      ++stats_.tiles;
      if (outline_) {
        append_outline_cells(level, first, count, tile.site, tile.boundary, threads_, outline_);
        reserve_for_rest(outline_, first + count - range_.first, range_.end - (first + count));
      } else {
        sink_({first, count, tile.site, tile.metres, tile.boundary});
      }
      progress(double(first + count - range_.first) / double(total), "label");
    }
  }

  const LabelOptions& options_;
  const std::function<void(const LabelTile&)>& sink_;
  OutlineCells* const outline_;
  std::future<double>* const given_back_;
  int threads_ = 0;
  DeviceChoice device_;
  grid::CodeRange range_;
  LabelStats stats_;
  bool hier_ = false;
  bool on_gpu_ = false;
  PreparedInput prepared_;
  CoverView cover_view_{};
  MemoryEstimate need_;
  std::vector<Piece> candidates_;
  bool candidates_made_ = false;
  std::unique_ptr<cuda::Labeller> gpu_;
  Tree tree_;
};

/// label_cells, or with `outline` label_outlines' pass (no sink then).
LabelStats run_labelling(const LabelInput& given, const LabelOptions& options,
                         const std::function<void(const LabelTile&)>& sink, OutlineCells* outline,
                         std::future<double>* given_back = nullptr) {
  return LabellingRun(options, sink, outline, given_back).run(given);
}

}  // namespace

LabelStats label_cells(const LabelInput& input, const LabelOptions& options,
                       const std::function<void(const LabelTile&)>& sink) {
  return run_labelling(input, options, sink, nullptr);
}

namespace {

/// The outline cells' count and memory, for QTMV_TRACE=label (the run's memory follows them).
void trace_outlines(const Outlines& o) {
  trace_printf(TraceStage::label, "outline cells %zu (%.1f MB held, %.1f MB reserved), %.1f per site",
               o.cells.size(), 1e-6 * static_cast<double>(o.cells.size() * sizeof(OutlineCell)),
               1e-6 * static_cast<double>(o.cells.capacity() * sizeof(OutlineCell)),
               static_cast<double>(o.cells.size()) / std::max(1.0, static_cast<double>(o.site_count)));
}

}  // namespace

LabelStats label_outlines(const LabelInput& input, const LabelOptions& options, Outlines* out) {
  const std::vector<DeviceChoice> devices = choose_devices(options.device);
  if (devices.size() > 1) {
    std::vector<std::string> names;
    for (const DeviceChoice& d : devices) names.push_back(cuda_device_name(d.index));
    return label_outlines_on(input, options, names, out);
  }
  LabelOptions outline_options = options;
  outline_options.want_distance = false;
  outline_options.want_boundary = true;
  Outlines result;
  result.level = input.level;
  result.site_count = input.site_count;
  result.range = range_of(options, input.level);
  // A GPU's memory is given back beside the count (0.1-0.3 s at a million sites, more where
  // several processes share the GPU), and waited for before the writers use the GPU.
  std::future<double> given_back;
  const LabelStats stats = run_labelling(input, outline_options, {}, &result.cells, &given_back);
  const double count_start = now_seconds();
  result.cells_per_site = count_cells_per_site(result.cells, input.level, input.site_count, result.range.end);
  trace_printf(TraceStage::label, "cells per site counted in %.3f s", now_seconds() - count_start);
  if (given_back.valid()) {
    const double wait_start = now_seconds();
    const double seconds = given_back.get();
    trace_printf(TraceStage::label, "%s: device memory given back in %.3f s beside the count, waited for %.3f s",
                 stats.device.c_str(), seconds, now_seconds() - wait_start);
  }
  trace_outlines(result);
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
  trace_outlines(joined);
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
