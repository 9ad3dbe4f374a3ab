// The labeller's device API (label_cuda.hpp): Labeller::Impl, what a Labeller holds on its
// device, and the public functions, each a thin sequence of checks, copies and the stages'
// launches: candidates_cuda.cu (the exact rule's pieces made here), tree_build_cuda.cu (the tree
// built here), painter_cuda.cu and brute_force_cuda.cu (the labels of a range of cells),
// outline_select_cuda.cu (their outline cells). Device memory: device_memory.cuh.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

#include "brute_force_cuda.cuh"
#include "candidates_cuda.cuh"
#include "device_memory.cuh"
#include "device_trace.cuh"
#include "label/label_cuda.hpp"
#include "label/label_engine.hpp"
#include "label/label_input.hpp"
#include "label/piece_groups.hpp"
#include "label_launch.cuh"
#include "outline_select_cuda.cuh"
#include "painter_cuda.cuh"
#include "tree_build_cuda.cuh"

namespace qtmv::label::cuda {

using device_memory::device_alloc;
using device_memory::device_copy;
using device_memory::DeviceArray;
using device_memory::fail_if_injected;
using device_memory::FaultStep;

int device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    (void)cudaGetLastError();  // no driver or no device: not an error here, just none
    return 0;
  }
  return count;
}

void warm_up(int device) {
  // The runtime creates the device's primary context on its first use; cudaFree(nullptr) is
  // such a use that does nothing else. Failures are left for the labelling to report.
  if (cudaSetDevice(device) != cudaSuccess || cudaFree(nullptr) != cudaSuccess) (void)cudaGetLastError();
}

void release_cached_memory(int device) {
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  QTMV_CUDA_CHECK(device_memory::release_pool(device));
}

DeviceInfo device_info(int device) {
  cudaDeviceProp prop{};
  QTMV_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  DeviceInfo info;
  info.name = prop.name;
  char bus[32];
  std::snprintf(bus, sizeof bus, "%04x:%02x:%02x", prop.pciDomainID, prop.pciBusID, prop.pciDeviceID);
  info.pci_bus_id = bus;
  QTMV_CUDA_CHECK(cudaMemGetInfo(&info.free_bytes, &info.total_bytes));
  info.pool_idle_bytes = device_memory::pool_idle_bytes(device);
  info.free_bytes += info.pool_idle_bytes;
  return info;
}

struct Labeller::Impl {
  int device = 0;
  int level = 0;
  bool hier = false;
  int piece_count = 0;
  DeviceArray<Piece> pieces;
  DeviceArray<PieceGroup> groups;  ///< the line runs' groups (empty: none)
  DeviceArray<TreeNode> nodes;
  DeviceArray<std::int32_t> lists;
  DeviceArray<JumpEntry> jump;
  int jump_level = 0;
  DeviceArray<std::uint8_t> jump_clean;  ///< per jump cell: jump_cell_clean
  TreeInfo tree_info;
  DeviceArray<std::int32_t> site;
  DeviceArray<float> metres;
  DeviceArray<std::uint8_t> boundary;
  DeviceArray<std::uint32_t> pending_spans;  ///< the paint spans with pending flags, and their count
  DeviceArray<unsigned int> counters;  ///< [0]: pending spans listed, [1]: the paint kernel's next span
  PaintGrids grids;                    ///< the painter's grids on this device
  std::uint64_t capacity = 0;
  std::size_t bytes = 0;
  std::size_t output_bytes = 0;
  OutlineSelection outline;  ///< select_outline's buffers
  cudaEvent_t start = nullptr, stop = nullptr;
  /// QTMV_FAULT_CUDA_OOM, read by open() and again by reserve() (FaultStep).
  FaultStep injected_fault = FaultStep::none;

  TreeView view() const {
    return {nodes.get(), lists.get(), pieces.get(), groups.get(), jump.get(), jump_level, level};
  }

  /// The constructors' common start: the device, its events, the level.
  void open(int device_index, int level_index, bool with_tree) {
    injected_fault = device_memory::injected_fault_step();
    device = device_index;
    level = level_index;
    hier = with_tree;
    QTMV_CUDA_CHECK(cudaSetDevice(device));
    grids = paint_grids(device);
    QTMV_CUDA_CHECK(cudaEventCreate(&start));
    QTMV_CUDA_CHECK(cudaEventCreate(&stop));
  }

  /// The groups of `plan` over the pieces already here, then the tree built here (`cover`: the
  /// fixed cells behind the pieces' fixed points, as build_tree's `fixed`).
  void build_tree(const GroupPlan& plan, bool with_distance, const CoverView& cover, DeviceTrace& trace) {
    trace("groups planned", plan.spans.size(), plan.top_items.size());
    if (!plan.spans.empty()) groups = make_device_groups(pieces.get(), plan.spans, &bytes, injected_fault);
    trace("groups made");
    DeviceTree t = build_on_device(device, pieces.get(), groups.get(), plan.top_items, level, with_distance, cover,
                                   injected_fault, trace);
    nodes = std::move(t.nodes);
    lists = std::move(t.lists);
    jump = std::move(t.jump);
    jump_level = t.jump_level;
    jump_clean = mark_clean_jump_cells(view(), &bytes, injected_fault);
    trace("jump cells marked");
    bytes += t.node_count * sizeof(TreeNode) + t.list_count * sizeof(std::int32_t) + t.jump_count * sizeof(JumpEntry);
    tree_info = {t.node_count, t.list_count, t.jump_count, t.jump_level, t.mean_candidates};
  }

  /// The time (milliseconds) since `start` was recorded: records `stop` and waits for it.
  float elapsed_ms() {
    QTMV_CUDA_CHECK(cudaEventRecord(stop));
    QTMV_CUDA_CHECK(cudaEventSynchronize(stop));
    float ms = 0;
    QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, start, stop));
    return ms;
  }

  void free_outputs() {
    outline.free_device();
    site.reset();
    metres.reset();
    boundary.reset();
    pending_spans.reset();
    counters.reset();
    bytes -= output_bytes;
    output_bytes = 0;
    capacity = 0;
  }
  ~Impl() {
    // Destructors must not throw; errors here are left to the next call's check.
    free_outputs();
    pieces.reset();
    groups.reset();
    nodes.reset();
    lists.reset();
    jump.reset();
    jump_clean.reset();
    if (start) cudaEventDestroy(start);
    if (stop) cudaEventDestroy(stop);
  }
};

Labeller::Labeller(int device, const std::vector<Piece>& candidates, const Tree* tree, int level)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, level, tree != nullptr);
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(candidates.size());
  m.pieces = device_copy(candidates, &m.bytes, m.injected_fault);
  if (tree) {
    m.groups = device_copy(tree->groups, &m.bytes, m.injected_fault);
    m.nodes = device_copy(tree->nodes, &m.bytes, m.injected_fault);
    m.lists = device_copy(tree->lists, &m.bytes, m.injected_fault);
    m.jump = device_copy(tree->jump, &m.bytes, m.injected_fault);
    m.jump_level = tree->jump_level;
    m.jump_clean = mark_clean_jump_cells(m.view(), &m.bytes, m.injected_fault);
  }
}

Labeller::Labeller(int device, const std::vector<Piece>& candidates, int level, bool with_distance,
                   int threads, const CoverView* cover_given)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, level, true);
  if (candidates.empty()) throw std::invalid_argument("build_tree: no candidates");
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(candidates.size());
  DeviceTrace trace;
  m.pieces = device_copy(candidates, &m.bytes, m.injected_fault);
  trace("pieces to the device", candidates.size());
  std::size_t scratch = 0;
  const DeviceCover cover = copy_cover(cover_given, level, &scratch, m.injected_fault);
  trace("cover to the device", cover.count);
  m.build_tree(plan_groups(candidates, host_threads(threads)), with_distance, cover.view(), trace);
}

Labeller::Labeller(int device, const LabelInput& input, bool with_distance, int threads,
                   const CoverView* cover_given)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.open(device, input.level, true);
  const std::size_t count = input.piece_count + input.fixed_cell_count;
  if (count == 0) throw std::invalid_argument("build_tree: no candidates");
  if (count > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(count);
  DeviceTrace trace;
  std::size_t cover_bytes = 0;
  const DeviceCover cover = copy_cover(cover_given, input.level, &cover_bytes, m.injected_fault);
  trace("cover to the device", cover.count);
  m.pieces = make_device_pieces(input, threads, &m.bytes, m.injected_fault, trace);
  trace("input to pieces", count);
  // The plan needs only the candidates' sites: the pieces', then the fixed cells' in ascending
  // order (their order's first key), from a count per site.
  std::vector<std::uint64_t> fixed_before(static_cast<std::size_t>(input.site_count) + 1, 0);
  for (std::size_t k = 0; k < input.fixed_cell_count; ++k) ++fixed_before[input.fixed_cells[k].site + 1];
  for (std::size_t s = 1; s < fixed_before.size(); ++s) fixed_before[s] += fixed_before[s - 1];
  const GroupPlan plan = plan_groups(
      static_cast<std::int64_t>(count),
      [&](std::int64_t k) {
        if (k < static_cast<std::int64_t>(input.piece_count)) return input.pieces[k].site;
        const auto f = static_cast<std::uint64_t>(k - static_cast<std::int64_t>(input.piece_count));
        return static_cast<std::int32_t>(std::upper_bound(fixed_before.begin(), fixed_before.end(), f) -
                                         fixed_before.begin() - 1);
      },
      host_threads(threads));
  m.build_tree(plan, with_distance, cover.view(), trace);
}

// Its arrays are freed on their device, whichever thread destroys it (labeller.cpp gives a GPU's
// memory back on a thread of its own).
Labeller::~Labeller() {
  if (impl_ && cudaSetDevice(impl_->device) != cudaSuccess) (void)cudaGetLastError();  // not left for the next check
}

TreeInfo Labeller::tree_info() const { return impl_->tree_info; }

void Labeller::download_tree(DefaultInitVector<TreeNode>* nodes, DefaultInitVector<std::int32_t>* lists,
                             DefaultInitVector<JumpEntry>* jump) const {
  const Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  nodes->resize(m.tree_info.nodes);
  lists->resize(m.tree_info.list_entries);
  jump->resize(m.tree_info.jump_entries);
  if (!nodes->empty()) {
    QTMV_CUDA_CHECK(cudaMemcpy(nodes->data(), m.nodes.get(), nodes->size() * sizeof(TreeNode), cudaMemcpyDeviceToHost));
  }
  if (!lists->empty()) {
    QTMV_CUDA_CHECK(
        cudaMemcpy(lists->data(), m.lists.get(), lists->size() * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  if (!jump->empty()) {
    QTMV_CUDA_CHECK(cudaMemcpy(jump->data(), m.jump.get(), jump->size() * sizeof(JumpEntry), cudaMemcpyDeviceToHost));
  }
}

void Labeller::reserve(std::uint64_t max_cells, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  m.free_outputs();
  m.injected_fault = device_memory::injected_fault_step();  // for this run's tiles
  if (max_cells > 65536) fail_if_injected(m.injected_fault, FaultStep::reserve);  // only large tiles: the caller tiles
  const std::size_t before = m.bytes;
  m.site = device_alloc<std::int32_t>(max_cells, &m.bytes, m.injected_fault);
  // brute needs the labels of a whole tile for its boundary pass; distances on request.
  if (want_distance) m.metres = device_alloc<float>(max_cells, &m.bytes, m.injected_fault);
  if (want_boundary) {
    m.boundary = device_alloc<std::uint8_t>(max_cells, &m.bytes, m.injected_fault);
    m.pending_spans = device_alloc<std::uint32_t>(paint_span_count(max_cells), &m.bytes, m.injected_fault);
  }
  m.counters = device_alloc<unsigned int>(2, &m.bytes, m.injected_fault);
  m.output_bytes = m.bytes - before;
  m.capacity = max_cells;
}

float Labeller::run(grid::Code first, std::uint64_t count, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  if (count > m.capacity) throw std::invalid_argument("Labeller::run: more cells than reserved");
  if ((want_distance && !m.metres) || (want_boundary && !m.boundary)) {
    throw std::invalid_argument("Labeller::run: outputs asked for that reserve() did not make room for");
  }
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  if (first > 0) fail_if_injected(m.injected_fault, FaultStep::run);  // after the first tile: a failure mid-run
  float* metres = want_distance ? m.metres.get() : nullptr;
  std::uint8_t* boundary = want_boundary ? m.boundary.get() : nullptr;
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (m.hier) {
    label_from_tree(m.view(), m.jump_clean.get(), m.grids, first, count, m.site.get(), metres, boundary,
                    m.pending_spans.get(), m.counters.get());
  } else {
    label_by_brute_force(m.pieces.get(), m.piece_count, m.level, first, count, m.site.get(), metres, boundary);
  }
  return m.elapsed_ms();
}

float Labeller::download(std::uint64_t offset, std::uint64_t count, std::int32_t* site, float* distance_m,
                         std::uint8_t* boundary) {
  Impl& m = *impl_;
  if (offset + count > m.capacity) throw std::invalid_argument("Labeller::download: outside the reserved cells");
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (site) {
    QTMV_CUDA_CHECK(cudaMemcpy(site, m.site.get() + offset, count * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  if (distance_m && m.metres) {
    QTMV_CUDA_CHECK(cudaMemcpy(distance_m, m.metres.get() + offset, count * sizeof(float), cudaMemcpyDeviceToHost));
  }
  if (boundary && m.boundary) {
    QTMV_CUDA_CHECK(cudaMemcpy(boundary, m.boundary.get() + offset, count, cudaMemcpyDeviceToHost));
  }
  return m.elapsed_ms();
}

float Labeller::select_outline(grid::Code first, std::uint64_t count, OutlineCells* out, std::uint64_t cells_left) {
  Impl& m = *impl_;
  if (count > m.capacity || !m.boundary) {
    throw std::invalid_argument("Labeller::select_outline: the last run had no flags for these cells");
  }
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  std::uint64_t chunk = std::min<std::uint64_t>(kOutlineChunkCells, m.capacity);
  // The tests make the buffer small (QTMV_FAULT_OUTLINE_BUFFER, cells; at least a segment's), so
  // that a tile's outline cells come in several runs.
  const std::string small = fault_switch("QTMV_FAULT_OUTLINE_BUFFER");
  if (!small.empty()) chunk = std::min(chunk, std::max<std::uint64_t>(kSelectSegmentCells, std::stoull(small)));
  if (!m.outline.allocated()) {
    // Counted in the outputs: reserve() freed the last ones, free_outputs() frees these.
    const std::size_t before = m.bytes;
    m.outline.allocate(chunk, m.capacity, &m.bytes, m.injected_fault);
    m.output_bytes += m.bytes - before;
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  m.outline.select(first, count, m.level, m.site.get(), m.boundary.get(), out, cells_left);
  return m.elapsed_ms();
}

std::vector<std::int32_t> Labeller::brute_sites(const std::vector<grid::Code>& codes) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  return brute_force_sites(m.pieces.get(), m.piece_count, m.level, codes, m.injected_fault);
}

std::size_t Labeller::device_bytes() const { return impl_->bytes; }

const std::int32_t* Labeller::device_sites() const { return impl_->site.get(); }

}  // namespace qtmv::label::cuda
