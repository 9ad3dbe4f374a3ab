// What every part of a run shares with its caller (GDAL-utility style): a progress callback that
// can stop the work, a sink for one-line messages with their severity, and the exception that
// says "stopped on request" as a type, never as a message text to be parsed.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

namespace qtmv {

/// debug: the trace channel's lines (common/trace.hpp), only when QTMV_TRACE asks for them.
enum class Severity { info, warning, debug };

/// Receives one-line messages for the user (informative lines, warnings, summaries).
using MessageSink = std::function<void(Severity severity, const std::string& message)>;

/// Called with the fraction done (0..1) and the stage's name; return false to stop the work.
using ProgressFunc = std::function<bool(double fraction, const char* stage)>;

/// The work stopped because a progress callback asked it to (Ctrl-C, a cancel button). Every
/// part throws this type; what a part had started writing is undone, as for any failure.
class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted") {}
};

/// Reports progress to `progress` (may be empty); throws Interrupted when it asks to stop.
inline void report_progress(const ProgressFunc& progress, double fraction, const char* stage) {
  if (progress && !progress(fraction, stage)) throw Interrupted();
}

/// Passes a message to `sink` (may be empty: the message is then dropped).
inline void tell(const MessageSink& sink, Severity severity, const std::string& message) {
  if (sink) sink(severity, message);
}

}  // namespace qtmv
