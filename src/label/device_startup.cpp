#include "label/device_startup.hpp"

#include <chrono>
#include <system_error>
#include <vector>

#include "common/device_spec.hpp"
#include "label/label_cuda.hpp"
#include "label/label_engine.hpp"
#include "label/labeller.hpp"

namespace qtmv::label {

DeviceStartup::DeviceStartup(const std::string& device, bool contexts) : count_(count_promise_.get_future().share()) {
  bool cpu = false;
  try {
    cpu = parse_device_spec(device).kind == DeviceSpec::Kind::cpu;
  } catch (const std::exception&) {
    // A bad name: counted all the same, for the plan's check, but nothing started.
  }
  if (cpu) {
    count_promise_.set_value(0);  // not counted: a CPU run uses none
    return;
  }
  thread_ = std::thread([this, device, contexts] {
    const int count = cuda_device_count();
    count_promise_.set_value(count);
    if (!contexts) return;
    std::vector<DeviceChoice> devices;
    try {
      devices = choose_devices(device);
    } catch (const std::exception&) {
      return;
    }
    // One thread a device; a thread the system cannot start leaves its context to the labelling.
    std::vector<std::thread> starts;
    try {
      for (const DeviceChoice& d : devices) {
        if (d.cuda) starts.emplace_back([index = d.index] { cuda::warm_up(index); });
      }
    } catch (const std::system_error&) {
    }
    for (std::thread& t : starts) t.join();
  });
}

DeviceStartup::~DeviceStartup() {
  if (thread_.joinable()) thread_.join();
}

int DeviceStartup::device_count() { return count_.get(); }

bool DeviceStartup::counted() const { return count_.wait_for(std::chrono::seconds(0)) == std::future_status::ready; }

void DeviceStartup::wait() {
  if (thread_.joinable()) thread_.join();
}

}  // namespace qtmv::label
