#include "common/device_spec.hpp"

#include <algorithm>
#include <stdexcept>

namespace qtmv {

DeviceSpec parse_device_spec(const std::string& text) {
  if (text == "auto") return {DeviceSpec::Kind::automatic, 0, {}, false};
  if (text == "cpu") return {DeviceSpec::Kind::cpu, 0, {}, false};
  if (text == "cuda") return {DeviceSpec::Kind::cuda, 0, {0}, false};
  if (text == "cuda:all") return {DeviceSpec::Kind::cuda, 0, {}, true};
  const std::string prefix = "cuda:";
  const auto bad = [&]() { return std::invalid_argument("unknown device '" + text + "': use " + device_spec_forms()); };
  if (text.size() <= prefix.size() || text.compare(0, prefix.size(), prefix) != 0) throw bad();
  DeviceSpec spec{DeviceSpec::Kind::cuda, 0, {}, false};
  for (std::size_t begin = prefix.size();;) {
    const std::size_t comma = std::min(text.find(',', begin), text.size());
    const std::string number = text.substr(begin, comma - begin);
    if (number.empty() || number.size() > 9 || number.find_first_not_of("0123456789") != std::string::npos) throw bad();
    const int ordinal = std::stoi(number);
    if (std::find(spec.indices.begin(), spec.indices.end(), ordinal) != spec.indices.end()) {
      throw std::invalid_argument("device '" + text + "' names cuda:" + number + " twice");
    }
    spec.indices.push_back(ordinal);
    if (comma == text.size()) break;
    begin = comma + 1;
  }
  spec.index = spec.indices.front();
  return spec;
}

}  // namespace qtmv
