// Facts about the host the run is on, and their wording for the user.
#pragma once

#include <cstdint>
#include <string>

namespace qtmv {

/// Seconds on a monotonic clock (for durations only).
double now_seconds();

/// Physical memory of the host (bytes); 8 GiB when the system does not say.
std::uint64_t host_ram_bytes();

/// This process's resident memory (bytes): now (VmRSS) and its high-water mark since it started
/// (VmHWM, what GNU time's "maximum resident set size" reports). Zeros where the system does not
/// say (no /proc/self/status).
struct ProcessMemory {
  std::uint64_t resident = 0;
  std::uint64_t peak_resident = 0;
};
ProcessMemory process_memory();

/// Memory the host can still give (bytes): the kernel's MemAvailable (free pages and the page
/// cache it can drop), or host_ram_bytes() where the system does not say (no /proc/meminfo).
std::uint64_t available_memory_bytes();

/// "1.25 GiB": a byte count for messages.
std::string format_gib(double bytes);

/// "a FIFO", "a socket" or "a device": what a path that is neither a regular file nor a
/// directory is, by its stat mode (st_mode), for a message refusing it.
const char* special_file_kind(unsigned mode);

}  // namespace qtmv
