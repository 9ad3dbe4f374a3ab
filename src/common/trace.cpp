#include "common/trace.hpp"

#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <mutex>
#include <utility>

#include "common/config_option.hpp"
#include "common/host_info.hpp"

namespace qtmv {

namespace {

std::mutex g_sink_mutex;
MessageSink g_sink;  // guarded by g_sink_mutex; empty: stderr

/// True when the word first .. last names `stage`.
bool names(const char* first, const char* last, TraceStage stage) {
  const char* name = trace_stage_name(stage);
  return static_cast<std::size_t>(last - first) == std::strlen(name) && std::strncmp(first, name, last - first) == 0;
}

}  // namespace

const char* trace_stage_name(TraceStage stage) {
  switch (stage) {
    case TraceStage::read: return "read";
    case TraceStage::label: return "label";
    case TraceStage::write: return "write";
  }
  return "";
}

bool trace_enabled(TraceStage stage) {
  if (!config_flag("QTMV_TRACE")) return false;  // unset, empty, NO, OFF, FALSE, 0
  const char* value = config_option("QTMV_TRACE");
  // A list of stages ("read,write", "label write"); any other value (all, YES, ON, 1) is every stage.
  bool listed_any = false;
  for (const char* p = value; *p;) {
    while (*p == ',' || *p == ' ') ++p;
    const char* end = p;
    while (*end && *end != ',' && *end != ' ') ++end;
    if (end == p) break;
    for (const TraceStage s : {TraceStage::read, TraceStage::label, TraceStage::write}) {
      if (names(p, end, s)) {
        listed_any = true;
        if (s == stage) return true;
      }
    }
    p = end;
  }
  return !listed_any;
}

void trace_line(TraceStage stage, const std::string& text) {
  const std::string line = std::string("trace: ") + trace_stage_name(stage) + " " + text;
  const std::lock_guard<std::mutex> lock(g_sink_mutex);
  if (g_sink) {
    g_sink(Severity::debug, line);
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
}

void trace_printf(TraceStage stage, const char* format, ...) {
  if (!trace_enabled(stage)) return;
  char text[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(text, sizeof text, format, args);
  va_end(args);
  trace_line(stage, text);
}

ScopedTraceSink::ScopedTraceSink(MessageSink sink) {
  const std::lock_guard<std::mutex> lock(g_sink_mutex);
  before_ = std::exchange(g_sink, std::move(sink));
}

ScopedTraceSink::~ScopedTraceSink() {
  const std::lock_guard<std::mutex> lock(g_sink_mutex);
  g_sink = std::move(before_);
}

StepTrace::StepTrace(TraceStage stage)
    : stage_(stage), on_(trace_enabled(stage)), last_(std::chrono::steady_clock::now()), last_cpu_(std::clock()) {}

void StepTrace::operator()(const char* step, const std::string& detail) {
  if (!on_) return;
  const auto now = std::chrono::steady_clock::now();
  char text[256];
  std::snprintf(text, sizeof text, "%-28s %9.3f ms", step, std::chrono::duration<double, std::milli>(now - last_).count());
  // The process's memory at the step's end, and its peak so far: where a step's buffers meet.
  // (Nothing where the system does not say: no /proc.)
  // And the CPU time of all the process's threads in the step: what a step costs a host shared
  // with other jobs (tile jobs at once), where its wall time says how long it took.
  const ProcessMemory memory = process_memory();
  const std::clock_t cpu = std::clock();
  const double cpu_seconds = static_cast<double>(cpu - last_cpu_) / CLOCKS_PER_SEC;
  char rss[128];
  if (memory.resident > 0) {
    std::snprintf(rss, sizeof rss, "  [rss %.1f MB, peak %.1f MB, cpu %.3f s]", memory.resident / 1e6,
                  memory.peak_resident / 1e6, cpu_seconds);
  } else {
    std::snprintf(rss, sizeof rss, "  [cpu %.3f s]", cpu_seconds);
  }
  trace_line(stage_, (detail.empty() ? std::string(text) : std::string(text) + "  " + detail) + rss);
  last_ = now;
  last_cpu_ = cpu;
}

void StepTrace::note(const char* what, double seconds) const {
  if (!on_) return;
  char text[256];
  std::snprintf(text, sizeof text, "  %-26s %9.3f ms", what, seconds * 1e3);
  trace_line(stage_, text);
}

}  // namespace qtmv
