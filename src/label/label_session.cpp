// The labelling session (label_session.hpp): the host's candidates and tree, built once, then
// ranges through the CPU's painter and lists through the per-cell walk.
#include "label/label_session.hpp"

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "grid/qtm_checks.hpp"
#include "label/cpu_painter.hpp"
#include "label/fixed_cover.hpp"
#include "label/label_engine.hpp"

namespace qtmv::label {

struct LabelSession::Impl {
  int level = 0;
  int threads = 1;
  bool with_distance = false;
  std::vector<Piece> candidates;
  Tree tree;
  TreeView view{};
  LabelStats stats;
};

LabelSession::LabelSession(const LabelInput& input, const LabelOptions& options) : impl_(std::make_unique<Impl>()) {
  check_label_input(input, options.rule);
  Impl& s = *impl_;
  s.level = input.level;
  s.threads = thread_count(options.threads);
  s.with_distance = options.want_distance;
  s.stats.device = "cpu (" + std::to_string(s.threads) + " threads)";
  s.stats.algorithm = Algorithm::hier;
  tell(options.messages, Severity::info, "labelling on " + s.stats.device + ", pruned tree (hier), on demand");
  const double t0 = now_seconds();
  report_progress(options.progress, 0.0, "prepare");
  // As label_cells prepares the tree: polygon interiors' fixed nodes as the tree's cover.
  const PreparedInput prepared = prepare_input(input, true, s.threads);
  const CoverView cover = prepared.cover.view();
  s.candidates = make_candidates(prepared.input, options.rule, s.threads);
  s.tree = build_tree(s.candidates, input.level, options.want_distance, s.threads,
                      [&](double fraction) { report_progress(options.progress, fraction, "prepare"); }, &cover);
  s.view = s.tree.view(s.candidates.data());
  s.stats.tree_nodes = s.tree.nodes.size();
  s.stats.tree_list_entries = s.tree.lists.size();
  s.stats.mean_candidates = s.tree.mean_candidates;
  s.stats.prepare_seconds = now_seconds() - t0;
}

LabelSession::~LabelSession() = default;

int LabelSession::level() const { return impl_->level; }
bool LabelSession::has_distance() const { return impl_->with_distance; }
const LabelStats& LabelSession::stats() const { return impl_->stats; }

std::uint64_t LabelSession::memory_bytes() const {
  const Impl& s = *impl_;
  const Tree& t = s.tree;
  return s.candidates.capacity() * sizeof(Piece) + t.nodes.capacity() * sizeof(TreeNode) +
         t.lists.capacity() * sizeof(std::int32_t) + t.jump.capacity() * sizeof(JumpEntry) +
         t.leaves.capacity() * sizeof(TreeLeaf) + t.groups.capacity() * sizeof(PieceGroup);
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
  cpu_tree_range(s.tree, s.view, first, count, site, distance_m, boundary, s.threads);
}

void LabelSession::label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                               std::uint8_t* boundary) const {
  const Impl& s = *impl_;
  if (distance_m && !s.with_distance) throw std::invalid_argument("this labelling session has no distances");
  const std::uint64_t cells = grid::cell_count(s.level);
  std::atomic<bool> bad{false};
  const std::int64_t n = static_cast<std::int64_t>(count);
#pragma omp parallel for num_threads(s.threads) schedule(dynamic, 4096)
  for (std::int64_t k = 0; k < n; ++k) {
    const grid::Code code = codes[k];
    if (code >= cells) {
      bad = true;
      continue;
    }
    tree_label_cell(s.view, code, site + k, distance_m ? distance_m + k : nullptr, boundary ? boundary + k : nullptr);
  }
  if (bad) throw std::invalid_argument("a code lies outside level " + std::to_string(s.level));
}

std::uint64_t session_jump_table_bytes(int level) {
  return grid::cell_count(tree_jump_level(level)) * sizeof(JumpEntry);
}

}  // namespace qtmv::label
