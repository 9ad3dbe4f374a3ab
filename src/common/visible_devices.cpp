#include "common/visible_devices.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>

namespace qtmv {

namespace {

/// The entries of a CUDA_VISIBLE_DEVICES value, trimmed; an empty entry ends the list (CUDA sees
/// nothing from it on, as from an invalid index), and so does an empty value.
std::vector<std::string> visible_entries(const std::string& value) {
  std::vector<std::string> entries;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t comma = std::min(value.find(',', begin), value.size());
    std::string entry = value.substr(begin, comma - begin);
    entry.erase(0, entry.find_first_not_of(" \t"));
    entry.erase(entry.find_last_not_of(" \t") + 1);
    if (entry.empty()) break;
    entries.push_back(entry);
    if (comma == value.size()) break;
    begin = comma + 1;
  }
  return entries;
}

VisibleDevices& process_devices() {
  static VisibleDevices devices;
  return devices;
}

}  // namespace

int VisibleDevices::ordinal_of(int user) const {
  if (!restricted) return user;
  for (std::size_t k = 0; k < named.size(); ++k) {
    if (named[k] == user) return static_cast<int>(k);
  }
  return -1;
}

int VisibleDevices::user_of(int ordinal) const {
  if (!restricted || ordinal < 0 || static_cast<std::size_t>(ordinal) >= named.size()) return ordinal;
  return named[static_cast<std::size_t>(ordinal)];
}

VisibleDevices plan_visible_devices(const DeviceSpec& spec, const char* user_value) {
  VisibleDevices v;
  if (spec.kind == DeviceSpec::Kind::cpu || spec.all) return v;
  const std::vector<int> wanted = spec.kind == DeviceSpec::Kind::automatic ? std::vector<int>{0} : spec.indices;
  const std::vector<std::string> shown = user_value ? visible_entries(user_value) : std::vector<std::string>{};
  v.restricted = true;
  for (const int user : wanted) {
    if (!v.value.empty()) v.value += ",";
    if (user_value && static_cast<std::size_t>(user) >= shown.size()) {
      v.value += "-1";  // the user does not see it: CUDA's enumeration ends here
      break;
    }
    v.value += user_value ? shown[static_cast<std::size_t>(user)] : std::to_string(user);
    v.named.push_back(user);
  }
  return v;
}

const VisibleDevices& restrict_visible_devices(const std::string& device) {
  DeviceSpec spec;
  try {
    spec = parse_device_spec(device);
  } catch (const std::invalid_argument&) {
    return process_devices();
  }
  const VisibleDevices v = plan_visible_devices(spec, std::getenv("CUDA_VISIBLE_DEVICES"));
  if (v.restricted) {
    setenv("CUDA_VISIBLE_DEVICES", v.value.c_str(), 1);
    process_devices() = v;
  }
  return process_devices();
}

const VisibleDevices& visible_devices() { return process_devices(); }

int cuda_ordinal(int user) { return visible_devices().ordinal_of(user); }

std::string cuda_device_name(int ordinal) { return "cuda:" + std::to_string(visible_devices().user_of(ordinal)); }

int first_missing_device(const DeviceSpec& spec, int cuda_count, const VisibleDevices& visible) {
  if (spec.kind != DeviceSpec::Kind::cuda) return -1;
  if (spec.all) return cuda_count > 0 ? -1 : 0;
  for (const int user : spec.indices) {
    const int ordinal = visible.ordinal_of(user);
    if (ordinal < 0 || ordinal >= cuda_count) return user;
  }
  return -1;
}

}  // namespace qtmv
