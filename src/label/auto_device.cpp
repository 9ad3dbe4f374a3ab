#include "label/auto_device.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "grid/qtm.hpp"
#include "label/outline_cells.hpp"

namespace qtmv::label {

namespace {

/// "2.2 M", "37.3 M", "2.1 G", "216 k".
std::string count_text(double n) {
  char text[32];
  if (n >= 1e9) {
    std::snprintf(text, sizeof text, "%.1f G", n / 1e9);
  } else if (n >= 1e6) {
    std::snprintf(text, sizeof text, "%.1f M", n / 1e6);
  } else {
    std::snprintf(text, sizeof text, "%.0f k", n / 1e3);
  }
  return text;
}

}  // namespace

double expected_outline_cells(int level, std::uint64_t sites) {
  const double boundary = 6.6 * std::sqrt(static_cast<double>(std::max<std::uint64_t>(sites, 1))) * 3.0 *
                          std::ldexp(1.0, level + 1) / 3.14159265358979;
  return static_cast<double>(row_end_count(level)) + std::min(boundary, static_cast<double>(grid::cell_count(level)));
}

AutoDevice choose_auto_device(const LabelWork& work) {
  AutoDevice choice;
  choice.threads = std::max(1, work.threads);
  const double cells = static_cast<double>(grid::cell_count(work.level));
  // The outline pass labels around the outline cells, or dense tiles every cell (where list
  // leaves hold many of them): whichever is less.
  const double outline =
      work.outlines ? work.share * std::min(cells, kCellsPerOutlineCell * expected_outline_cells(work.level, work.sites))
                    : 0.0;
  choice.work_cells =
      outline + static_cast<double>(work.every_cell) + kCellsPerCandidate * static_cast<double>(work.candidates);
  choice.start_cells = kGpuStartSeconds * std::min(choice.threads, kCpuScalingThreads) / kCpuSecondsPerCell;
  choice.gpu = choice.work_cells > choice.start_cells;
  return choice;
}

std::string AutoDevice::reason() const {
  return count_text(work_cells) + " cells of work, " + (gpu ? "above" : "below") + " the GPU's start (" +
         count_text(start_cells) + " on " + std::to_string(threads) + " thread" + (threads == 1 ? "" : "s") + ")";
}

}  // namespace qtmv::label
