// The device tree build's launches and scans (the kernels: tree_build_kernels.cuh): level by
// level as build_tree (src/label/tree_build.cpp) does on the host.
//
// One level at a time, every (node, parent-list entry) pair is one work item; per node the
// nearest candidate's squared chord, then the kept entries compacted in list order by a scan, and
// the nodes' kinds, offsets and children from scans in node order (tree_build_kernels.cuh says
// how). The scratch of the levels comes from the device's default memory pool (PoolBuffer).
#include "tree_build_cuda.cuh"

#include <cub/device/device_scan.cuh>

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "label_launch.cuh"
#include "tree_build_kernels.cuh"

namespace qtmv::label::cuda {

using device_memory::DeviceArray;
using device_memory::device_alloc;
using device_memory::FaultStep;
using device_memory::PoolBuffer;

DeviceCover copy_cover(const CoverView* cover, int level, std::size_t* bytes, FaultStep injected) {
  DeviceCover out;
  out.level = level;
  if (cover == nullptr || cover->count == 0) return out;
  const std::uint64_t n = cover->count;
  out.first = device_alloc<std::uint64_t>(n, bytes, injected);
  out.last = device_alloc<std::uint64_t>(n, bytes, injected);
  out.site = device_alloc<std::int32_t>(n, bytes, injected);
  out.owner_run = device_alloc<std::int32_t>(n, bytes, injected);
  QTMV_CUDA_CHECK(cudaMemcpy(out.first.get(), cover->first, n * sizeof(std::uint64_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(cudaMemcpy(out.last.get(), cover->last, n * sizeof(std::uint64_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(cudaMemcpy(out.site.get(), cover->site, n * sizeof(std::int32_t), cudaMemcpyHostToDevice));
  QTMV_CUDA_CHECK(
      cudaMemcpy(out.owner_run.get(), cover->owner_run, n * sizeof(std::int32_t), cudaMemcpyHostToDevice));
  out.count = n;
  out.split_partly = cover->split_partly;
  return out;
}

DeviceArray<PieceGroup> make_device_groups(const Piece* pieces, const std::vector<GroupSpan>& spans,
                                           std::size_t* bytes, FaultStep injected) {
  std::size_t span_bytes = 0;
  const DeviceArray<GroupSpan> device_spans = device_memory::device_copy(spans, &span_bytes, injected);
  const auto count = static_cast<std::int32_t>(spans.size());
  DeviceArray<PieceGroup> groups = device_alloc<PieceGroup>(spans.size(), bytes, injected);
  make_groups_kernel<<<blocks_for(std::uint64_t{32} * spans.size()), kBlock>>>(pieces, device_spans.get(), count,
                                                                               groups.get());
  QTMV_CUDA_CHECK_LAUNCH("make_groups_kernel");
  return groups;
}

namespace {

/// One build's levels: the level being built (its nodes and their parent lists' entries), the
/// tree so far, and the levels' scratch, each a pool buffer that grows as the levels do.
struct LevelBuild {
  const Piece* pieces;
  const PieceGroup* runs;
  int level;
  bool with_distance;
  int list_level;
  CoverView cover;
  DeviceTrace& trace;

  std::uint64_t n = 0;        ///< nodes of the level being built
  std::uint64_t entries = 0;  ///< their parent lists' entries (4 per item: the groups share lists)
  std::uint64_t node_count = 0, list_count = 0;
  double weighted = 0;  ///< list entries weighted by the cells below them (mean_candidates)

  PoolBuffer<DevPending> pending, next;
  PoolBuffer<std::int32_t> parent_lists, next_lists;
  PoolBuffer<TreeNode> nodes;
  PoolBuffer<std::int32_t> lists;
  PoolBuffer<Vec3> centre;
  PoolBuffer<double> radius, threshold;
  PoolBuffer<unsigned long long> start_in, start, min_bits, key;
  PoolBuffer<unsigned long long> point_bits;  ///< per node: the nearest point item's squared chord (bits)
  PoolBuffer<std::int32_t> reference;         ///< per node: that point item, the bisector rule's reference
  PoolBuffer<std::int32_t> site_min, site_max, kind, count, value;
  PoolBuffer<unsigned long long> keep, keep_pos;  // 64 bits: a loose group may refine to many items
  PoolBuffer<std::int32_t> owner_heads, owner;
  PoolBuffer<LevelSums> sums_in, offsets;
  PoolBuffer<unsigned char> temp;

  void scan_temp(std::size_t bytes) { temp.need(bytes ? bytes : 1); }

  /// Level 0: the eight octants, each with the runs' top items.
  void start_octants(const std::vector<std::int32_t>& top_items) {
    n = grid::kOctants;
    const auto top_count = static_cast<std::uint32_t>(top_items.size());
    entries = n * top_count;
    DevPending roots[grid::kOctants];
    for (int o = 0; o < grid::kOctants; ++o) roots[o] = {grid::Cell{o, 0, 0}, o, top_count, 0};
    pending.need(n);
    QTMV_CUDA_CHECK(cudaMemcpy(pending.get(), roots, sizeof roots, cudaMemcpyHostToDevice));
    parent_lists.need(top_count);
    QTMV_CUDA_CHECK(
        cudaMemcpy(parent_lists.get(), top_items.data(), top_count * sizeof(std::int32_t), cudaMemcpyHostToDevice));
    node_count = grid::kOctants;
    list_count = 0;
    nodes.grow_keep(node_count, 0);
  }

  /// The level's scratch, for n nodes and `entries` entries.
  void size_scratch() {
    centre.need(n);
    radius.need(n);
    threshold.need(n);
    start_in.need(n + 1);
    start.need(n + 1);
    min_bits.need(n);
    point_bits.need(n);
    reference.need(n);
    key.need(n);
    site_min.need(n);
    site_max.need(n);
    kind.need(n);
    count.need(n);
    value.need(n);
    sums_in.need(n + 1);
    offsets.need(n + 1);
    keep.need(entries + 1);
    keep_pos.need(entries + 1);
  }

  /// Per node its centre, radius and list start (a scan of the parent lists' lengths).
  void init_nodes(int l, bool last, std::int32_t nn) {
    level_init_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, l, last, centre.get(), radius.get(), start_in.get(),
                                                min_bits.get(), site_min.get(), site_max.get(), key.get(),
                                                point_bits.get(), reference.get());
    QTMV_CUDA_CHECK_LAUNCH("level_init_kernel");
    std::size_t bytes = 0;
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, start_in.get(), start.get(), n + 1));
    scan_temp(bytes);
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.get(), bytes, start_in.get(), start.get(), n + 1));
  }

  /// The work items' passes: at the labelling level each node's winner; above it each item's
  /// owner, the nodes' thresholds and reference points (the bisector rule), and the items each
  /// entry keeps (keep).
  void bound_items(bool last, std::int32_t nn) {
    // Groups of four nodes share a list (n and entries are multiples of 4).
    const std::int32_t groups = nn / 4;
    const std::uint64_t items = entries / 4;
    if (last) {
      level_settle_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, parent_lists.get(), pieces, runs, centre.get(),
                                                    key.get());
      QTMV_CUDA_CHECK_LAUNCH("level_settle_kernel");
      return;
    }
    owner_heads.need(items);
    owner.need(items);
    QTMV_CUDA_CHECK(cudaMemsetAsync(owner_heads.get(), 0, items * sizeof(std::int32_t)));
    level_owner_kernel<<<blocks_of(groups), kBlock>>>(start.get(), groups, owner_heads.get());
    QTMV_CUDA_CHECK_LAUNCH("level_owner_kernel");
    std::size_t owner_bytes = 0;
    QTMV_CUDA_CHECK(
        cub::DeviceScan::InclusiveScan(nullptr, owner_bytes, owner_heads.get(), owner.get(), MaxI32{}, items));
    scan_temp(owner_bytes);
    QTMV_CUDA_CHECK(
        cub::DeviceScan::InclusiveScan(temp.get(), owner_bytes, owner_heads.get(), owner.get(), MaxI32{}, items));
    level_min_kernel<<<blocks_of(items), kBlock>>>(pending.get(), owner.get(), start.get(), items, parent_lists.get(),
                                                   pieces, runs, centre.get(), min_bits.get(), point_bits.get());
    QTMV_CUDA_CHECK_LAUNCH("level_min_kernel");
    level_reference_kernel<<<blocks_of(items), kBlock>>>(pending.get(), owner.get(), start.get(), items,
                                                         parent_lists.get(), pieces, runs, centre.get(),
                                                         point_bits.get(), reference.get());
    QTMV_CUDA_CHECK_LAUNCH("level_reference_kernel");
    level_threshold_kernel<<<blocks_of(n), kBlock>>>(nn, min_bits.get(), radius.get(), threshold.get());
    QTMV_CUDA_CHECK_LAUNCH("level_threshold_kernel");
    level_keep_kernel<<<blocks_of(items), kBlock>>>(pending.get(), owner.get(), start.get(), items, parent_lists.get(),
                                                    pieces, runs, centre.get(), radius.get(), threshold.get(),
                                                    reference.get(), keep.get(), site_min.get(), site_max.get());
    QTMV_CUDA_CHECK_LAUNCH("level_keep_kernel");
  }

  /// keep_pos: where each entry's kept items go (a scan of keep).
  void scan_kept() {
    QTMV_CUDA_CHECK(cudaMemset(keep.get() + entries, 0, sizeof(unsigned long long)));
    std::size_t bytes = 0;
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, keep.get(), keep_pos.get(), entries + 1));
    scan_temp(bytes);
    QTMV_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.get(), bytes, keep.get(), keep_pos.get(), entries + 1));
  }

  /// Per node its kind (decide_node) and offsets (a scan in node order); returns the level's
  /// totals.
  LevelSums decide_nodes(int l, bool last, std::int32_t nn) {
    level_decide_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, l, last, with_distance, l >= list_level, cover,
                                                  start.get(), keep_pos.get(), site_min.get(), site_max.get(),
                                                  key.get(), kind.get(), count.get(), value.get(), sums_in.get());
    QTMV_CUDA_CHECK_LAUNCH("level_decide_kernel");
    std::size_t bytes = 0;
    const LevelSums zero{0, 0, 0};
    QTMV_CUDA_CHECK(
        cub::DeviceScan::ExclusiveScan(nullptr, bytes, sums_in.get(), offsets.get(), AddSums{}, zero, n + 1));
    scan_temp(bytes);
    QTMV_CUDA_CHECK(
        cub::DeviceScan::ExclusiveScan(temp.get(), bytes, sums_in.get(), offsets.get(), AddSums{}, zero, n + 1));
    LevelSums total{};
    QTMV_CUDA_CHECK(cudaMemcpy(&total, offsets.get() + n, sizeof total, cudaMemcpyDeviceToHost));
    if (node_count + 4 * total.internals > 0x7fffffffull || list_count + total.leaf_entries > 0x7fffffffull) {
      throw std::length_error("the labeller's tree outgrew 2^31 nodes or list entries");
    }
    return total;
  }

  /// The level's nodes, the next level's pending nodes and the lists (the leaves' and the next
  /// level's parent lists).
  void write_level(bool last, std::int32_t nn, const LevelSums& total) {
    nodes.grow_keep(node_count + 4 * total.internals, node_count);
    lists.grow_keep(list_count + total.leaf_entries + 1, list_count);
    next.need(4 * total.internals + 1);
    next_lists.need(total.internal_entries + 1);
    level_write_nodes_kernel<<<blocks_of(n), kBlock>>>(pending.get(), nn, last, kind.get(), count.get(), value.get(),
                                                       key.get(), offsets.get(), list_count, node_count, nodes.get(),
                                                       lists.get());
    QTMV_CUDA_CHECK_LAUNCH("level_write_nodes_kernel");
    if (total.internals > 0) {
      level_write_children_kernel<<<blocks_of(4 * n), kBlock>>>(pending.get(), nn, kind.get(), count.get(),
                                                                offsets.get(), node_count, next.get());
      QTMV_CUDA_CHECK_LAUNCH("level_write_children_kernel");
    }
    if (!last && entries > 0) {
      level_write_lists_kernel<<<blocks_of(entries / 4), kBlock>>>(
          pending.get(), owner.get(), start.get(), entries / 4, parent_lists.get(), pieces, runs, centre.get(),
          radius.get(), threshold.get(), keep_pos.get(), kind.get(), offsets.get(), list_count, lists.get(),
          next_lists.get());
      QTMV_CUDA_CHECK_LAUNCH("level_write_lists_kernel");
    }
  }

  /// Builds level l (n > 0 nodes pending) and makes the next level's nodes pending.
  void build_level(int l) {
    const bool last = l == level;
    // Nodes are counted in 32 bits (keep_pos: 64).
    if (n > 0x7ffffffful) {
      // std::length_error: label_cells falls back to the host build.
      throw std::length_error("the labeller's tree level " + std::to_string(l) +
                              " has too many nodes or entries to be built on the device");
    }
    const std::int32_t nn = static_cast<std::int32_t>(n);
    if (n % 4 != 0 || entries % 4 != 0) throw std::logic_error("build_on_device: nodes not in groups of four");
    size_scratch();
    init_nodes(l, last, nn);
    if (entries > 0) bound_items(last, nn);
    if (!last) scan_kept();
    const LevelSums total = decide_nodes(l, last, nn);
    write_level(last, nn, total);
    weighted += static_cast<double>(entries) +
                static_cast<double>(total.leaf_entries) * std::ldexp(1.0, 2 * (level - l));
    trace(last ? "level (last)" : "level", n, entries);
    node_count += 4 * total.internals;
    list_count += total.leaf_entries;
    n = 4 * total.internals;
    entries = 4 * total.internal_entries;
    std::swap(pending, next);
    std::swap(parent_lists, next_lists);
  }

  /// The jump table, and the tree's arrays copied out of the scratch.
  DeviceTree finish(FaultStep injected) {
    DeviceTree t;
    t.jump_level = tree_jump_level(level);
    t.jump_count = grid::cell_count(t.jump_level);
    t.jump = DeviceArray<JumpEntry>::plain(t.jump_count, injected);
    jump_kernel<<<blocks_of(t.jump_count), kBlock>>>(nodes.get(), t.jump_level, t.jump_count, t.jump.get());
    QTMV_CUDA_CHECK_LAUNCH("jump_kernel");
    t.node_count = node_count;
    t.list_count = list_count;
    t.mean_candidates = weighted / static_cast<double>(grid::cell_count(level));
    t.nodes = nodes.copy_out(node_count, injected);
    t.lists = lists.copy_out(list_count, injected);
    trace("jump table, copies", t.jump_count, list_count);
    return t;
  }
};

}  // namespace

DeviceTree build_on_device(int device, const Piece* pieces, const PieceGroup* runs,
                           const std::vector<std::int32_t>& top_items, int level, bool with_distance,
                           const CoverView& cover, FaultStep injected, DeviceTrace& trace) {
  device_memory::fail_if_injected(injected, FaultStep::build);
  // The scratch comes from the device's default pool and stays there (pool_idle_bytes).
  cudaMemPool_t pool;
  QTMV_CUDA_CHECK(cudaDeviceGetDefaultMemPool(&pool, device));
  {
    std::uint64_t keep_all = ~std::uint64_t{0};
    QTMV_CUDA_CHECK(cudaMemPoolSetAttribute(pool, cudaMemPoolAttrReleaseThreshold, &keep_all));
  }
  // A build that throws (too large: label_cells then builds on the host) gives the pool's memory
  // back too, or the tiles would be sized from too little free memory. Errors are moot there.
  struct TrimOnThrow {
    cudaMemPool_t pool;
    bool done = false;
    ~TrimOnThrow() {
      if (done) return;
      cudaDeviceSynchronize();
      cudaMemPoolTrimTo(pool, std::size_t{256} << 20);
    }
  } trim_on_throw{pool};
  DeviceTree t;  // a build that throws frees the tree's arrays with it
  {
    LevelBuild build{pieces, runs, level, with_distance, tree_list_level(level), cover, trace};
    build.start_octants(top_items);
    for (int l = 0; l <= level && build.n > 0; ++l) build.build_level(l);
    t = build.finish(injected);
  }  // the scratch goes back to the pool here
  QTMV_CUDA_CHECK(cudaDeviceSynchronize());
  trim_on_throw.done = true;
  return t;
}

}  // namespace qtmv::label::cuda
