// The trace channel of every stage (GDAL's CPLDebug under CPL_DEBUG is the model): each step's
// time and size, for tuning. One switch, QTMV_TRACE, read through config_option (so the
// environment, or `--config QTMV_TRACE ...` in the tool): "all" (or YES, ON, TRUE, 1) traces every
// stage; a list such as "read,write" traces those stages (read, label, write). Lines go to the
// run's MessageSink at Severity::debug (ScopedTraceSink; the tool prints them on stderr), or to
// stderr when no run installed one (the benchmarks, the tests). A line reads
// "trace: <stage> <text>".
#pragma once

#include <chrono>
#include <ctime>
#include <string>

#include "common/run_context.hpp"

namespace qtmv {

/// The stages a trace line belongs to.
enum class TraceStage { read, label, write };

/// "read", "label" or "write".
const char* trace_stage_name(TraceStage stage);

/// True when QTMV_TRACE asks for `stage`'s lines. Cheap enough to call per step, not per cell.
bool trace_enabled(TraceStage stage);

/// Writes "trace: <stage> <text>" through the installed sink (one line at a time, from any
/// thread), whether or not the stage is enabled: callers test trace_enabled first.
void trace_line(TraceStage stage, const std::string& text);

/// printf-style trace_line, written only when `stage` is enabled.
void trace_printf(TraceStage stage, const char* format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/// Routes trace lines to `sink` at Severity::debug for its lifetime (a run's messages), and
/// restores the sink before. One run at a time per process, as ScopedDefaultThreads.
class ScopedTraceSink {
 public:
  explicit ScopedTraceSink(MessageSink sink);
  ~ScopedTraceSink();
  ScopedTraceSink(const ScopedTraceSink&) = delete;
  ScopedTraceSink& operator=(const ScopedTraceSink&) = delete;

 private:
  MessageSink before_;
};

/// The steps of one stage, each traced with its time since the step before:
/// "trace: <stage> <step> <milliseconds> ms <detail>  [rss <MB> MB, peak <MB> MB, cpu <s> s]" (the
/// process's resident memory at the step's end and its peak so far, 10^6 bytes: common/host_info.hpp's
/// process_memory, where the system says; the CPU time of all its threads in the step, seconds).
/// Off (and free) unless the stage is enabled.
class StepTrace {
 public:
  explicit StepTrace(TraceStage stage);
  /// Whether the stage is traced (a caller that must prepare a step, e.g. wait for a device).
  bool on() const { return on_; }
  /// Traces the time since the last step (or construction, or restart) as `step`.
  void operator()(const char* step, const std::string& detail = {});
  /// Starts the next step's clock now (what ran since the last step is not traced).
  void restart() {
    last_ = std::chrono::steady_clock::now();
    last_cpu_ = std::clock();
  }
  /// Traces a figure of the step just traced: `what`, `seconds` (seconds), indented below it.
  void note(const char* what, double seconds) const;

 private:
  TraceStage stage_;
  bool on_;
  std::chrono::steady_clock::time_point last_;
  std::clock_t last_cpu_;
};

}  // namespace qtmv
