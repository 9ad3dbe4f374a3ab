// Host-side argument checks for the grid, with messages meant for users.
#pragma once

#include <stdexcept>
#include <string>

#include "qtm_code.hpp"

namespace qtmv::grid {

/// Throws std::invalid_argument naming the level when it is outside kMinLevel..kMaxLevel.
inline void require_level(int level) {
  if (!is_valid_level(level)) {
    throw std::invalid_argument("QTM level " + std::to_string(level) + " is out of range: levels " +
                                std::to_string(kMinLevel) + " to " + std::to_string(kMaxLevel) + " are supported");
  }
}

/// Throws std::invalid_argument naming the code and the level when the code is not a cell of it.
inline void require_code(Code code, int level) {
  require_level(level);
  if (!is_valid_code(code, level)) {
    throw std::invalid_argument("QTM code " + std::to_string(code) + " is out of range at level " +
                                std::to_string(level) + ": codes run from 0 to " +
                                std::to_string(cell_count(level) - 1));
  }
}

}  // namespace qtmv::grid
