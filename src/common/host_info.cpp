#include "common/host_info.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>

namespace qtmv {

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::uint64_t host_ram_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page)
                               : std::uint64_t{8} << 30;
}

ProcessMemory process_memory() {
  ProcessMemory memory;
  std::FILE* status = std::fopen("/proc/self/status", "r");
  if (!status) return memory;
  char line[256];
  while (std::fgets(line, sizeof line, status)) {
    unsigned long long kib = 0;  // the kernel's "kB" are KiB
    if (std::sscanf(line, "VmRSS: %llu kB", &kib) == 1) memory.resident = kib * 1024;
    if (std::sscanf(line, "VmHWM: %llu kB", &kib) == 1) memory.peak_resident = kib * 1024;
  }
  std::fclose(status);
  return memory;
}

std::uint64_t available_memory_bytes() {
  std::FILE* info = std::fopen("/proc/meminfo", "r");
  if (!info) return host_ram_bytes();
  char line[256];
  unsigned long long kib = 0;
  bool found = false;
  while (!found && std::fgets(line, sizeof line, info)) found = std::sscanf(line, "MemAvailable: %llu kB", &kib) == 1;
  std::fclose(info);
  return found ? kib * 1024 : host_ram_bytes();
}

std::string format_gib(double bytes) {
  char text[64];
  std::snprintf(text, sizeof text, "%.2f GiB", bytes / double(std::uint64_t{1} << 30));
  return text;
}

const char* special_file_kind(unsigned mode) {
  return S_ISFIFO(mode) ? "a FIFO" : S_ISSOCK(mode) ? "a socket" : "a device";
}

}  // namespace qtmv
