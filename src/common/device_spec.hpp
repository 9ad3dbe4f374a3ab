// The -device argument, parsed once: auto | cpu | cuda | cuda:N.
#pragma once

#include <string>

namespace qtmv {

struct DeviceSpec {
  enum class Kind { automatic, cpu, cuda };
  Kind kind = Kind::automatic;
  int index = 0;  ///< the CUDA device's ordinal (cuda: 0; cuda:N: N)
};

/// Parses "auto", "cpu", "cuda" or "cuda:N" (N a non-negative decimal number). Throws
/// std::invalid_argument naming the text and the accepted forms.
DeviceSpec parse_device_spec(const std::string& text);

/// The accepted forms, for messages: "auto, cpu, cuda or cuda:N".
inline const char* device_spec_forms() { return "auto, cpu, cuda or cuda:N"; }

}  // namespace qtmv
