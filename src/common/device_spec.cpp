#include "common/device_spec.hpp"

#include <climits>
#include <stdexcept>

namespace qtmv {

DeviceSpec parse_device_spec(const std::string& text) {
  if (text == "auto") return {DeviceSpec::Kind::automatic, 0};
  if (text == "cpu") return {DeviceSpec::Kind::cpu, 0};
  if (text == "cuda") return {DeviceSpec::Kind::cuda, 0};
  const std::string prefix = "cuda:";
  if (text.size() > prefix.size() && text.size() <= prefix.size() + 9 && text.compare(0, prefix.size(), prefix) == 0 &&
      text.find_first_not_of("0123456789", prefix.size()) == std::string::npos) {
    return {DeviceSpec::Kind::cuda, std::stoi(text.substr(prefix.size()))};
  }
  throw std::invalid_argument("unknown device '" + text + "': use " + device_spec_forms());
}

}  // namespace qtmv
