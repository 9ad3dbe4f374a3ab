// The labeller's CUDA back end, as the host code sees it (plain C++; cuda/label_cuda.cu
// implements it on the stages' .cu files beside it). Without CUDA the build links
// label_cuda_stub.cpp, which reports no device and throws on use.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/device_out_of_memory.hpp"
#include "grid/qtm.hpp"
#include "label/label_engine.hpp"
#include "label/label_math.hpp"
#include "label/label_tree.hpp"
#include "label/tree_node_rule.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {
struct Tree;
struct LabelInput;
struct FixedCell;
}

namespace qtmv::label::cuda {

/// A device allocation failed (cudaErrorMemoryAllocation): the caller may retry with smaller
/// tiles or go on on the CPU. (The tests inject it: QTMV_FAULT_CUDA_OOM, see
/// cuda/device_memory.cuh.)
using OutOfMemory = DeviceOutOfMemory;

/// Outline cells select_outline holds on the device at once; its buffers take at most
/// kOutlineSelectBytesPerCell bytes for each of them (the outline cells, and the counts and
/// offsets of the tile's segments: 16 bytes per 4096 cells, which the 4 bytes cover for tiles of
/// up to 2^35 cells), on top of the tile's outputs.
constexpr std::uint64_t kOutlineChunkCells = std::uint64_t{1} << 25;
constexpr std::uint64_t kOutlineSelectBytesPerCell = 4 + sizeof(OutlineCell);

/// Number of CUDA devices the runtime can use (0 when there is no driver or no device).
int device_count();

/// Creates the device's context (what the first CUDA call of a process pays: tenths of a second),
/// so that the labelling finds it ready: for a thread of its own while the sites are read. Never
/// throws; a device that fails is reported when it is used.
void warm_up(int device);

/// The device tree build keeps its scratch in the device's default memory pool, so that the next
/// build need not map it again (tens of milliseconds at level 15); this gives it back to the
/// system. label_cells calls it when it is done with a device.
void release_cached_memory(int device);

struct DeviceInfo {
  std::string name;
  std::string pci_bus_id;           ///< "domain:bus:device" (hexadecimal), which no restriction renumbers
  std::size_t free_bytes = 0;       ///< free, plus what the labeller's memory pool holds idle
  std::size_t pool_idle_bytes = 0;  ///< of free_bytes, what that pool holds idle
  std::size_t total_bytes = 0;
};
DeviceInfo device_info(int device);

/// Size of a tree built on the device.
struct TreeInfo {
  std::uint64_t nodes = 0;
  std::uint64_t list_entries = 0;
  std::uint64_t jump_entries = 0;
  int jump_level = 0;
  double mean_candidates = 0;  ///< as Tree::mean_candidates
};

/// One labelling job on one GPU: the candidates (and for `hier` the tree) live on the device;
/// run() computes a range of codes into device buffers, download() brings them to the host.
class Labeller {
 public:
  /// tree == nullptr: brute force over all candidates. Throws std::runtime_error on CUDA errors.
  Labeller(int device, const std::vector<Piece>& candidates, const Tree* tree, int level);
  /// `hier` with the tree built on the device, level by level: the tree of build_tree
  /// (tree_build.cpp), node for node and entry for entry. host_threads: CPU threads for the host's
  /// share (the line runs' plan), as LabelOptions::threads (0: all). `cover` (host arrays, may be
  /// null): the claimed cells, as build_tree's.
  Labeller(int device, const std::vector<Piece>& candidates, int level, bool with_distance, int host_threads = 0,
           const CoverView* cover = nullptr);
  /// The same for the exact rule, with the candidates made on the device from the input (the
  /// pieces of make_candidates(input, Rule::exact), which the host then need not make; the
  /// input's fixed nodes, if any, are not made into pieces: give their cells as fixed cells).
  Labeller(int device, const LabelInput& input, bool with_distance, int host_threads = 0,
           const CoverView* cover = nullptr);
  ~Labeller();
  /// Size of the device-built tree (zeros for the other constructor).
  TreeInfo tree_info() const;
  /// Copies the device-built tree to the host (for the tests).
  void download_tree(DefaultInitVector<TreeNode>* nodes, DefaultInitVector<std::int32_t>* lists,
                     DefaultInitVector<JumpEntry>* jump) const;
  Labeller(const Labeller&) = delete;
  Labeller& operator=(const Labeller&) = delete;

  /// Makes room on the device for the outputs of up to max_cells cells.
  void reserve(std::uint64_t max_cells, bool want_distance, bool want_boundary);
  /// Labels codes [first, first + count) (count <= reserved); returns the kernels' time
  /// (milliseconds, CUDA events). Outputs stay on the device until download().
  float run(grid::Code first, std::uint64_t count, bool want_distance, bool want_boundary);
  /// Copies cells [offset, offset + count) of the last run to host arrays (null: skipped).
  /// Returns the copy's time (milliseconds).
  float download(std::uint64_t offset, std::uint64_t count, std::int32_t* site, float* distance_m,
                 std::uint8_t* boundary);
  /// Appends the outline cells (outline_cells.hpp) of the last run's cells [0, count), codes
  /// first.., to *out, counted and written on the device segment by segment (CUB's scan); the run
  /// must have had boundary flags. `cells_left`: the cells of the range still to be labelled
  /// after these, for which *out is given room at this tile's rate (and a tenth more) when it
  /// grows, so that it grows once, not again (a copy of all it holds) for the next tile.
  /// Returns the time (milliseconds) of selection and copies.
  float select_outline(grid::Code first, std::uint64_t count, OutlineCells* out, std::uint64_t cells_left = 0);
  /// Bytes this object holds on the device now.
  std::size_t device_bytes() const;
  /// The float64 brute-force labels of the given codes (the reference of the benchmark's check).
  std::vector<std::int32_t> brute_sites(const std::vector<grid::Code>& codes);
  /// Device address of the last run's labels (for checks that stay on the device).
  const std::int32_t* device_sites() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace qtmv::label::cuda
