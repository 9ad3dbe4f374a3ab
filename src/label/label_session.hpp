// A labelling session: the labeller prepared once for one level (candidates and the `hier`
// tree, as label_cells prepares them), then asked for the labels of any range of codes or any
// list of codes, as often as a caller likes, into the caller's buffers. A writer that streams
// (the raster writer, strip by strip) holds only the labels of what it is writing.
//
// The labels are those of label_cells, cell for cell (site, distance, boundary flag): ranges
// go through the CPU's painter (cpu_tree_range), lists through the per-cell walk
// (tree_label_cell, which needs no label array and looks a cell's neighbours up in the tree),
// points along parallels through the leaves they meet (tree_label_parallels), all on all CPU
// cores. The jump table of every cell's walk (up to 256 MiB) is built on the first list: the
// painter and the parallels need only the coarse one of the outline pass. The session always uses the tree on the CPU, whatever
// LabelOptions::algorithm and device say: every algorithm and device gives the same labels.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "grid/qtm.hpp"
#include "label/label_input.hpp"
#include "label/labeller.hpp"

namespace qtmv::label {

class LabelSession {
 public:
  /// Checks the input (as label_cells does: std::invalid_argument) and builds the candidates
  /// and the tree of input.level. Uses options.rule, threads, want_distance (without it no
  /// distances can be asked for later), progress (the build, stage "prepare"; false stops it
  /// with Interrupted) and messages. The input's arrays are not used after the constructor.
  LabelSession(const LabelInput& input, const LabelOptions& options);
  ~LabelSession();
  LabelSession(const LabelSession&) = delete;
  LabelSession& operator=(const LabelSession&) = delete;

  int level() const;
  bool has_distance() const;
  /// Where and how it labels ("cpu (N threads)"), the build's time and the tree's size.
  const LabelStats& stats() const;
  /// Host bytes the session holds (candidates, tree, cover; on a GPU the input's copy).
  std::uint64_t memory_bytes() const;

  /// The labels of codes [first, first + count) into site[count], distance_m[count] (metres;
  /// may be null, must be null without want_distance) and boundary[count] (0/1; may be null).
  /// Throws std::invalid_argument for codes outside the level.
  void label_range(grid::Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const;
  /// The labels of codes[0..count) (any order; sorted codes label faster) into the same arrays,
  /// entry k for codes[k].
  void label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const;
  /// The labels of the cells that hold the points (lon[k], lat[r]), r < rows, k < count (degrees:
  /// a lon/lat raster's rows of pixel centres; lat in [-90, 90], lon in [-180, 180), best
  /// ascending) into the same arrays, entry r * count + k: the labels of grid::lonlat_to_code's
  /// cells, found along each parallel through the tree's leaves (parallel_labels.hpp), without
  /// the codes listed. Throws std::invalid_argument for a coordinate outside those ranges.
  void label_parallels(const double* lat, int rows, const double* lon, std::size_t count, std::int32_t* site,
                       float* distance_m, std::uint8_t* boundary) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Bytes of the tree's jump table at `level` (an entry per cell of tree_jump_level): the part of
/// a session's memory that grows with the level (at most 256 MiB, from level 14 up).
std::uint64_t session_jump_table_bytes(int level);

}  // namespace qtmv::label
