// The trace channel and the run switches (common/trace.hpp, common/config_option.hpp): which
// values of QTMV_TRACE switch which stages on, that lines go through the installed sink at
// Severity::debug (and nowhere when off), and that an installed lookup replaces the environment.
#include "common/trace.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/config_option.hpp"
#include "common/host_info.hpp"

namespace qtmv {
namespace {

/// Sets QTMV_TRACE (nullptr: unsets it) for its lifetime.
class TraceSwitch {
 public:
  explicit TraceSwitch(const char* value) {
    if (value) {
      ::setenv("QTMV_TRACE", value, 1);
    } else {
      ::unsetenv("QTMV_TRACE");
    }
  }
  ~TraceSwitch() { ::unsetenv("QTMV_TRACE"); }
};

std::vector<bool> stages_on() {
  return {trace_enabled(TraceStage::read), trace_enabled(TraceStage::label), trace_enabled(TraceStage::write)};
}

TEST(Trace, StagesFollowTheSwitch) {
  using V = std::vector<bool>;
  const std::vector<std::pair<const char*, V>> cases = {
      {nullptr, {false, false, false}}, {"", {false, false, false}},    {"NO", {false, false, false}},
      {"off", {false, false, false}},   {"0", {false, false, false}},   {"all", {true, true, true}},
      {"YES", {true, true, true}},      {"1", {true, true, true}},      {"write", {false, false, true}},
      {"read,label", {true, true, false}}, {"label write", {false, true, true}},
  };
  for (const auto& [value, expected] : cases) {
    const TraceSwitch on(value);
    EXPECT_EQ(stages_on(), expected) << (value ? value : "(unset)");
  }
}

TEST(Trace, LinesGoToTheSinkAtDebugSeverityOnlyWhenOn) {
  std::vector<std::pair<Severity, std::string>> lines;
  const ScopedTraceSink sink([&](Severity s, const std::string& m) { lines.emplace_back(s, m); });
  {
    const TraceSwitch on("write");
    StepTrace write(TraceStage::write);
    StepTrace read(TraceStage::read);
    EXPECT_TRUE(write.on());
    EXPECT_FALSE(read.on());
    write("rows written", "42 rows");
    write.note("of which tracing", 0.5);
    read("features examined");
    trace_printf(TraceStage::write, "raster %d strips", 3);
    trace_printf(TraceStage::label, "host level %d", 1);
  }
  ASSERT_EQ(lines.size(), 3u);
  for (const auto& [severity, text] : lines) EXPECT_EQ(severity, Severity::debug) << text;
  EXPECT_EQ(lines[0].second.rfind("trace: write rows written ", 0), 0u) << lines[0].second;
  EXPECT_NE(lines[0].second.find(" ms  42 rows"), std::string::npos) << lines[0].second;
  EXPECT_NE(lines[1].second.find("of which tracing"), std::string::npos) << lines[1].second;
  EXPECT_NE(lines[1].second.find("500.000 ms"), std::string::npos) << lines[1].second;
  EXPECT_EQ(lines[2].second, "trace: write raster 3 strips");
  // A step's line ends with the process's memory: now and its peak so far (where /proc says).
  if (process_memory().resident > 0) {
    EXPECT_NE(lines[0].second.find("42 rows  [rss "), std::string::npos) << lines[0].second;
    EXPECT_NE(lines[0].second.find(" MB, peak "), std::string::npos) << lines[0].second;
    EXPECT_TRUE(std::regex_search(lines[0].second, std::regex(" MB, cpu [0-9]+\\.[0-9]{3} s\\]$"))) << lines[0].second;
  } else {
    EXPECT_EQ(lines[0].second.find("[rss "), std::string::npos) << lines[0].second;
    EXPECT_TRUE(std::regex_search(lines[0].second, std::regex("  \\[cpu [0-9]+\\.[0-9]{3} s\\]$"))) << lines[0].second;
  }
}

TEST(Trace, AStepsCpuTimeIsTheProcessesWorkNotItsWaiting) {
  // 80 ms of work on this thread, then 80 ms asleep: the first step's CPU time about the work,
  // the second's about none.
  std::vector<std::pair<Severity, std::string>> lines;
  {
    const TraceSwitch on("write");
    const ScopedTraceSink sink([&](Severity s, const std::string& m) { lines.emplace_back(s, m); });
    StepTrace write(TraceStage::write);
    volatile double sum = 0;
    for (const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(80); std::chrono::steady_clock::now() < end;) {
      sum = sum + 1.0;
    }
    write("busy");
    std::this_thread::sleep_for(std::chrono::milliseconds(80));
    write("asleep");
  }
  ASSERT_EQ(lines.size(), 2u);
  const auto cpu_of = [](const std::string& line) {
    std::smatch m;
    EXPECT_TRUE(std::regex_search(line, m, std::regex("cpu ([0-9.]+) s\\]$"))) << line;
    return m.empty() ? -1.0 : std::stod(m[1]);
  };
  EXPECT_GT(cpu_of(lines[0].second), 0.05) << lines[0].second;
  EXPECT_LT(cpu_of(lines[1].second), 0.03) << lines[1].second;
}

TEST(ProcessMemory, IsPlausibleAndGrowsWithTouchedMemory) {
#if defined(__linux__)
  const ProcessMemory before = process_memory();
  if (before.resident == 0) GTEST_SKIP() << "no /proc/self/status (a sandbox without /proc)";
  EXPECT_GT(before.resident, std::uint64_t{1} << 20);  // a test binary holds more than a MiB
  EXPECT_LT(before.resident, host_ram_bytes());
  EXPECT_GE(before.peak_resident, before.resident);
  // 64 MiB touched page by page: resident now, and in the peak.
  constexpr std::size_t kBytes = std::size_t{64} << 20;
  const std::unique_ptr<char[]> buffer(new char[kBytes]);
  for (std::size_t k = 0; k < kBytes; k += 4096) buffer[k] = static_cast<char>(k);
  volatile char sink = buffer[kBytes / 2];
  (void)sink;
  const ProcessMemory after = process_memory();
  EXPECT_GE(after.resident, before.resident + kBytes * 9 / 10);
  EXPECT_GE(after.peak_resident, after.resident);
  EXPECT_GE(after.peak_resident, before.peak_resident);
#else
  GTEST_SKIP() << "no /proc/self/status";
#endif
}

TEST(AvailableMemory, IsAtMostTheHostsAndAtLeastAPage) {
  // MemAvailable never exceeds MemTotal (sysconf's physical pages), and a running test has some.
  const std::uint64_t available = available_memory_bytes();
  EXPECT_LE(available, host_ram_bytes());
  EXPECT_GE(available, std::uint64_t{4096});
}

const char* fake_lookup(const char* name, const char*) {
  return std::strcmp(name, "QTMV_FAULT_TEST") == 0 ? "allocate" : nullptr;
}

TEST(ConfigOption, AnInstalledLookupReplacesTheEnvironment) {
  ::setenv("QTMV_FAULT_OTHER", "build", 1);
  EXPECT_EQ(fault_switch("QTMV_FAULT_OTHER"), "build");
  EXPECT_EQ(fault_switch("QTMV_FAULT_TEST"), "");
  set_config_lookup(&fake_lookup);
  EXPECT_EQ(fault_switch("QTMV_FAULT_TEST"), "allocate");
  EXPECT_EQ(fault_switch("QTMV_FAULT_OTHER"), "");  // the lookup decides, not the environment
  set_config_lookup(nullptr);
  EXPECT_EQ(fault_switch("QTMV_FAULT_OTHER"), "build");
  ::unsetenv("QTMV_FAULT_OTHER");
}

}  // namespace
}  // namespace qtmv
