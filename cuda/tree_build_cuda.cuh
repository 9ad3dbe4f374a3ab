// The tree built on the device (tree_build_cuda.cu), as the labeller's device API (label_cuda.cu)
// calls it: the tree of build_tree (src/label/tree_build.cpp), node for node and list entry for
// list entry, with the same node rule (tree_node_rule.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "device_memory.cuh"
#include "device_trace.cuh"
#include "label/label_math.hpp"
#include "label/label_tree.hpp"
#include "label/piece_groups.hpp"
#include "label/tree_node_rule.hpp"

namespace qtmv::label::cuda {

/// The cover (fixed_cover.hpp) copied to the device, as the device build looks it up.
struct DeviceCover {
  device_memory::DeviceArray<std::uint64_t> first, last;
  device_memory::DeviceArray<std::int32_t> site, owner_run;
  std::uint64_t count = 0;
  int level = 0;
  bool split_partly = false;
  CoverView view() const {
    return {first.get(), last.get(), site.get(), owner_run.get(), count, level, split_partly};
  }
};

/// `cover` (host arrays, may be null: none) on the current device, its bytes added to *bytes.
DeviceCover copy_cover(const CoverView* cover, int level, std::size_t* bytes, device_memory::FaultStep injected);

/// The line runs' groups of `spans` over the pieces on the device (make_groups, one warp a
/// group), their bytes added to *bytes.
device_memory::DeviceArray<PieceGroup> make_device_groups(const Piece* pieces, const std::vector<GroupSpan>& spans,
                                                          std::size_t* bytes, device_memory::FaultStep injected);

/// What build_on_device made: the tree's arrays.
struct DeviceTree {
  device_memory::DeviceArray<TreeNode> nodes;
  device_memory::DeviceArray<std::int32_t> lists;
  device_memory::DeviceArray<JumpEntry> jump;
  std::uint64_t node_count = 0, list_count = 0, jump_count = 0;
  int jump_level = 0;
  double mean_candidates = 0;
};

/// The tree of build_tree (tree_build.cpp), built on the current device; `cover`: the claimed
/// cells (DeviceCover; count 0: none). `injected`: QTMV_FAULT_CUDA_OOM as the Labeller read it.
/// Throws std::length_error for a tree too large to build here (the caller builds on the host).
DeviceTree build_on_device(int device, const Piece* pieces, const PieceGroup* runs,
                           const std::vector<std::int32_t>& top_items, int level, bool with_distance,
                           const CoverView& cover, device_memory::FaultStep injected, DeviceTrace& trace);

}  // namespace qtmv::label::cuda
