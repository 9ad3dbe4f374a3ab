// The CUDA devices of a run, counted and started on a thread of their own. The driver's start
// takes tenths of a second a process (measured on an H100 host: the runtime's initialisation,
// which counting the devices does, 0.1-0.2 s; a context per device, 0.1 s), so a run starts
// them first and checks them once its sites are read, instead of waiting for them before.
#pragma once

#include <future>
#include <string>
#include <thread>

namespace qtmv::label {

class DeviceStartup {
 public:
  /// Counts the CUDA devices, then, with `contexts`, makes the contexts of those that `device`
  /// (a -device value, LabelOptions::device) names, all at once. Nothing for "cpu"; a bad name
  /// starts no context (the run's plan reports it). Never throws from the thread: a failing
  /// device is reported when the labelling uses it.
  DeviceStartup(const std::string& device, bool contexts);
  /// Waits for the thread.
  ~DeviceStartup();
  DeviceStartup(const DeviceStartup&) = delete;
  DeviceStartup& operator=(const DeviceStartup&) = delete;

  /// Usable CUDA devices on this host (cuda_device_count), 0 for "cpu" (not counted); waits for
  /// the count, not for the contexts.
  int device_count();
  /// Whether device_count() answers without waiting.
  bool counted() const;
  /// Waits until the contexts are made.
  void wait();

 private:
  std::promise<int> count_promise_;
  std::shared_future<int> count_;
  std::thread thread_;
};

}  // namespace qtmv::label
