// The -device argument, parsed once: auto | cpu | cuda | cuda:N | cuda:N,M,... | cuda:all.
#pragma once

#include <string>
#include <vector>

namespace qtmv {

struct DeviceSpec {
  enum class Kind { automatic, cpu, cuda };
  Kind kind = Kind::automatic;
  int index = 0;             ///< the first CUDA device's ordinal (cuda: 0; cuda:N,...: N)
  std::vector<int> indices;  ///< cuda: the listed ordinals, in the order given ({0} for cuda); empty for all
  bool all = false;          ///< cuda:all: every CUDA device of the host
  /// More than one GPU may label (a list of several, or all).
  bool several() const { return all || indices.size() > 1; }
};

/// Parses "auto", "cpu", "cuda", "cuda:N", "cuda:N,M,..." (non-negative decimal ordinals, each
/// once) or "cuda:all". Throws std::invalid_argument naming the text and the accepted forms.
DeviceSpec parse_device_spec(const std::string& text);

/// The accepted forms, for messages.
inline const char* device_spec_forms() { return "auto, cpu, cuda, cuda:N, a list cuda:N,M,... or cuda:all"; }

}  // namespace qtmv
