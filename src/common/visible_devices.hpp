// The CUDA devices a process lets CUDA see. CUDA counts and initialises every visible device at
// its first call (on a 4-GPU host `-device cuda:0` took 0.92-1.47 s at level 6, against
// 0.49-0.53 s with CUDA_VISIBLE_DEVICES=0), so a tool restricts CUDA_VISIBLE_DEVICES to the
// devices its -device names before any CUDA call, and keeps the user's names: cuda:N is always
// the N-th device the user's own environment shows (CUDA_VISIBLE_DEVICES and CUDA_DEVICE_ORDER
// as the user set them), in every message, trace and summary.
#pragma once

#include <string>
#include <vector>

#include "common/device_spec.hpp"

namespace qtmv {

/// What CUDA is to see of the host's devices for one -device value.
struct VisibleDevices {
  bool restricted = false;  ///< CUDA_VISIBLE_DEVICES is set to `value`; else CUDA sees what the user's environment shows
  std::string value;        ///< restricted: CUDA_VISIBLE_DEVICES, the devices asked for in the order asked
  /// restricted: the user's N (cuda:N) of each CUDA ordinal of the process, in order; a device
  /// the user's environment does not show ends the list (CUDA then counts only those before it).
  std::vector<int> named;

  /// The process's CUDA ordinal of the user's cuda:N; -1 when the restriction hides it.
  int ordinal_of(int user) const;
  /// The user's N of the process's CUDA ordinal.
  int user_of(int ordinal) const;
};

/// The restriction for `spec`, composed with the user's CUDA_VISIBLE_DEVICES (`user_value`, null
/// when unset: the user's cuda:N is then CUDA's ordinal N; set: its N-th entry, index or UUID).
/// None for cpu (no CUDA call at all) and cuda:all (every device); auto: the first device (the
/// one it would use). A device past the user's list becomes "-1", which ends CUDA's enumeration
/// there. Pure.
VisibleDevices plan_visible_devices(const DeviceSpec& spec, const char* user_value);

/// Sets CUDA_VISIBLE_DEVICES for the -device value `device` (plan_visible_devices against the
/// environment) and makes it the process's (visible_devices()). For a tool's main, once, before
/// any thread and any CUDA call: after CUDA has started the variable is not read again, and the
/// names would be wrong. A value that does not parse changes nothing (the run reports it).
const VisibleDevices& restrict_visible_devices(const std::string& device);

/// The process's restriction (none unless restrict_visible_devices was called).
const VisibleDevices& visible_devices();

/// The process's CUDA ordinal of the user's cuda:N (N unless restricted; -1: hidden).
int cuda_ordinal(int user);

/// "cuda:N": the user's name of the process's CUDA ordinal.
std::string cuda_device_name(int ordinal);

/// The user's N of the first device of `spec` (a cuda spec) that is missing when CUDA counts
/// `cuda_count` devices under `visible`; -1 when none is.
int first_missing_device(const DeviceSpec& spec, int cuda_count, const VisibleDevices& visible = visible_devices());

}  // namespace qtmv
