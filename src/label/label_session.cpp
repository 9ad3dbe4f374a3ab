// The labelling session (label_session.hpp): the candidates and the tree, built once, then
// ranges on the GPU (cuda::Labeller, the device-built tree) or through the CPU's painter, and
// lists through the per-cell walk of the host's tree.
#include "label/label_session.hpp"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "common/trace.hpp"
#include "common/visible_devices.hpp"
#include "grid/qtm_checks.hpp"
#include "label/cpu_painter.hpp"
#include "label/fixed_cover.hpp"
#include "label/label_cuda.hpp"
#include "label/label_engine.hpp"
#include "label/parallel_labels.hpp"

namespace qtmv::label {

/// Cells a GPU session labels per run (and the device buffers it reserves): the writers' strips
/// are smaller.
constexpr std::uint64_t kSessionDeviceCells = std::uint64_t{1} << 26;

struct LabelSession::Impl {
  int level = 0;
  int threads = 1;
  bool with_distance = false;
  Rule rule = Rule::exact;
  // The input as prepared (its arrays are the caller's, the copies below or `prepared`'s).
  PreparedInput prepared;
  std::vector<Piece> candidates;
  Tree tree;
  TreeView view{};  ///< the tree with its coarse jump table (JumpTable::outline)
  // The jump table of every cell's walk (tree_jump_level), built on the first list of codes.
  mutable std::once_flag full_jump_once;
  mutable DefaultInitVector<JumpEntry> full_jump;
  mutable TreeView full_view{};
  std::unique_ptr<LeafRows> leaf_rows;  ///< the host tree's leaves by rows, for the painter
  LabelStats stats;
  std::unique_ptr<cuda::Labeller> gpu;  ///< ranges on the GPU when set
  std::uint64_t gpu_cells = 0;
  // The host's tree, built on the first list of codes when the ranges go to the GPU.
  mutable std::once_flag host_tree;
  std::vector<FixedCell> fixed_copy;
  std::vector<FixedNode> nodes_copy;
  std::vector<SitePiece> pieces_copy;
  std::vector<SiteCell> site_cells_copy;

  void build_host_tree(const ProgressFunc& progress) {
    const CoverView cover = prepared.cover.view();
    candidates = make_candidates(prepared.input, rule, threads);
    tree = build_tree(candidates, level, with_distance, threads,
                      [&](double fraction) { report_progress(progress, fraction, "prepare"); }, &cover,
                      JumpTable::outline);
    view = tree.view(candidates.data());
    leaf_rows = std::make_unique<LeafRows>(tree);
    stats.tree_nodes = tree.nodes.size();
    stats.tree_list_entries = tree.lists.size();
    stats.mean_candidates = tree.mean_candidates;
  }

  /// Before a look-up on the host: the host's tree (a GPU session builds it on the first), and
  /// distances only where the session has them.
  void ready_on_host(bool want_distance) {
    if (gpu) std::call_once(host_tree, [&] { build_host_tree({}); });
    if (want_distance && !with_distance) throw std::invalid_argument("this labelling session has no distances");
  }

  /// The tree with the jump table of every cell's walk, for the per-cell walk of lists.
  const TreeView& walk_view() const {
    std::call_once(full_jump_once, [&] {
      const double t0 = now_seconds();
      full_jump = make_jump_table(tree.nodes.data(), tree_jump_level(level), threads);  // `tree` keeps the coarse one
      full_view = view;
      full_view.jump = full_jump.data();
      full_view.jump_level = tree_jump_level(level);
      trace_printf(TraceStage::label, "host jump table %9.3f ms  %zu entries of level %d (the session's first list of codes)",
                   (now_seconds() - t0) * 1e3, full_jump.size(), full_view.jump_level);
    });
    return full_view;
  }
};

LabelSession::LabelSession(const LabelInput& input, const LabelOptions& options) : impl_(std::make_unique<Impl>()) {
  check_label_input(input, options.rule);
  Impl& s = *impl_;
  s.level = input.level;
  s.threads = thread_count(options.threads);
  s.with_distance = options.want_distance;
  s.rule = options.rule;
  const double t0 = now_seconds();
  report_progress(options.progress, 0.0, "prepare");
  const DeviceChoice device = choose_device(options.device);
  LabelInput own = input;
  if (device.cuda) {
    // The session keeps its own copy of the input, for a host tree built later (lists).
    s.pieces_copy.assign(input.pieces, input.pieces + input.piece_count);
    s.site_cells_copy.assign(input.site_cells, input.site_cells + input.site_cell_count);
    s.fixed_copy.assign(input.fixed_cells, input.fixed_cells + input.fixed_cell_count);
    s.nodes_copy.assign(input.fixed_nodes, input.fixed_nodes + input.fixed_node_count);
    own.pieces = s.pieces_copy.data();
    own.site_cells = s.site_cells_copy.data();
    own.fixed_cells = s.fixed_copy.data();
    own.fixed_nodes = s.nodes_copy.data();
  }
  // As label_cells prepares the tree: polygon interiors' fixed nodes as the tree's cover.
  s.prepared = prepare_input(own, true);
  if (device.cuda) {
    // Ranges on the GPU, with the tree built there; a GPU that cannot hold it leaves the work
    // to the CPU.
    try {
      const CoverView cover = s.prepared.cover.view();
      s.gpu = s.rule == Rule::exact
                  ? std::make_unique<cuda::Labeller>(device.index, s.prepared.input, s.with_distance, s.threads, &cover)
                  : std::make_unique<cuda::Labeller>(device.index, make_candidates(s.prepared.input, s.rule, s.threads),
                                                     input.level, s.with_distance, s.threads, &cover);
      s.gpu_cells = std::min<std::uint64_t>(grid::cell_count(input.level), kSessionDeviceCells);
      s.gpu->reserve(s.gpu_cells, s.with_distance, true);
      const cuda::TreeInfo info = s.gpu->tree_info();
      s.stats.tree_nodes = info.nodes;
      s.stats.tree_list_entries = info.list_entries;
      s.stats.mean_candidates = info.mean_candidates;
      s.stats.device = cuda_device_name(device.index) + " (" + cuda::device_info(device.index).name + ")";
    } catch (const std::exception& e) {
      s.gpu.reset();
      tell(options.messages, Severity::warning,
           std::string("the GPU cannot label this raster (") + e.what() + "); labelling on the CPU instead");
    }
  }
  if (!s.gpu) {
    s.stats.device = "cpu (" + std::to_string(s.threads) + " threads)";
    s.build_host_tree(options.progress);
  }
  s.stats.algorithm = Algorithm::hier;
  tell(options.messages, Severity::info, "labelling on " + s.stats.device + ", pruned tree (hier), on demand");
  s.stats.prepare_seconds = now_seconds() - t0;
}

LabelSession::~LabelSession() = default;

int LabelSession::level() const { return impl_->level; }
bool LabelSession::has_distance() const { return impl_->with_distance; }
const LabelStats& LabelSession::stats() const { return impl_->stats; }

std::uint64_t LabelSession::memory_bytes() const {
  const Impl& s = *impl_;
  const Tree& t = s.tree;
  const FixedCover& c = s.prepared.cover;
  return s.candidates.capacity() * sizeof(Piece) + t.nodes.capacity() * sizeof(TreeNode) +
         t.lists.capacity() * sizeof(std::int32_t) + (t.jump.capacity() + s.full_jump.capacity()) * sizeof(JumpEntry) +
         t.leaves.capacity() * sizeof(TreeLeaf) + t.groups.capacity() * sizeof(PieceGroup) +
         s.pieces_copy.capacity() * sizeof(SitePiece) + s.site_cells_copy.capacity() * sizeof(SiteCell) +
         (s.fixed_copy.capacity() + s.prepared.fixed_cells.capacity()) * sizeof(FixedCell) +
         s.nodes_copy.capacity() * sizeof(FixedNode) + (c.first.capacity() + c.last.capacity()) * 8 +
         (c.site.capacity() + c.owner_run.capacity()) * 4 + (s.leaf_rows ? s.leaf_rows->memory_bytes() : 0);
}

void LabelSession::label_range(grid::Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                               std::uint8_t* boundary) const {
  const Impl& s = *impl_;
  if (distance_m && !s.with_distance) throw std::invalid_argument("this labelling session has no distances");
  const std::uint64_t cells = grid::cell_count(s.level);
  if (first > cells || count > cells - first) {
    throw std::invalid_argument("codes " + std::to_string(first) + " + " + std::to_string(count) +
                                " lie outside level " + std::to_string(s.level));
  }
  if (count == 0) return;
  if (s.gpu) {
    for (std::uint64_t done = 0; done < count; done += s.gpu_cells) {
      const std::uint64_t n = std::min(s.gpu_cells, count - done);
      s.gpu->run(first + done, n, distance_m != nullptr, boundary != nullptr);
      s.gpu->download(0, n, site + done, distance_m ? distance_m + done : nullptr, boundary ? boundary + done : nullptr);
    }
    return;
  }
  // The painter visits the leaves that meet the range; it walks the tree only for the neighbours
  // of the range's first and last rows: the coarse jump table serves.
  cpu_tree_range(s.tree, s.view, first, count, site, distance_m, boundary, s.threads, s.leaf_rows.get());
}

void LabelSession::label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                               std::uint8_t* boundary) const {
  Impl& s = *impl_;
  s.ready_on_host(distance_m != nullptr);
  const std::uint64_t cells = grid::cell_count(s.level);
  std::atomic<bool> bad{false};
  const TreeView& view = s.walk_view();
  const std::int64_t n = static_cast<std::int64_t>(count);
#pragma omp parallel for num_threads(s.threads) schedule(dynamic, 4096)
  for (std::int64_t k = 0; k < n; ++k) {
    const grid::Code code = codes[k];
    if (code >= cells) {
      bad = true;
      continue;
    }
    tree_label_cell(view, code, site + k, distance_m ? distance_m + k : nullptr, boundary ? boundary + k : nullptr);
  }
  if (bad) throw std::invalid_argument("a code lies outside level " + std::to_string(s.level));
}

void LabelSession::label_parallels(const double* lat, int rows, const double* lon, std::size_t count,
                                   std::int32_t* site, float* distance_m, std::uint8_t* boundary) const {
  Impl& s = *impl_;
  s.ready_on_host(distance_m != nullptr);
  for (int r = 0; r < rows; ++r) {
    if (!(lat[r] >= -90.0 && lat[r] <= 90.0)) throw std::invalid_argument("a latitude lies outside [-90, 90]");
  }
  for (std::size_t k = 0; k < count; ++k) {
    if (!(lon[k] >= -180.0 && lon[k] < 180.0)) throw std::invalid_argument("a longitude lies outside [-180, 180)");
  }
  tree_label_parallels(s.view, lat, rows, lon, count, site, distance_m, boundary, s.threads);
}

std::uint64_t session_jump_table_bytes(int level) {
  return grid::cell_count(tree_jump_level(level)) * sizeof(JumpEntry);
}

}  // namespace qtmv::label
