// Facts about the host the run is on, and their wording for the user.
#pragma once

#include <cstdint>
#include <string>

namespace qtmv {

/// Seconds on a monotonic clock (for durations only).
double now_seconds();

/// Physical memory of the host (bytes); 8 GiB when the system does not say.
std::uint64_t host_ram_bytes();

/// "1.25 GiB": a byte count for messages.
std::string format_gib(double bytes);

/// "a FIFO", "a socket" or "a device": what a path that is neither a regular file nor a
/// directory is, by its stat mode (st_mode), for a message refusing it.
const char* special_file_kind(unsigned mode);

}  // namespace qtmv
