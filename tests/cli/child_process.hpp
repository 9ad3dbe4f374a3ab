// Runs a built tool as a user would, for the command-line tests: arguments, standard input from
// a file, standard output and error to files (files, not pipes, so that nothing can deadlock),
// under a time limit so that a hang fails the test instead of blocking CI.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace qtmv::test {

struct ProcessResult {
  int status = -1;         ///< exit status, -1 when killed by a signal
  int signal = 0;          ///< the signal that killed it (a crash: SIGSEGV, SIGABRT...), else 0
  bool timed_out = false;  ///< killed by wait_process after its time limit
  std::string out, err;
};

/// What the child gets besides its arguments.
struct ChildSetup {
  long file_size_limit = -1;  ///< RLIMIT_FSIZE in bytes (ulimit -f), -1: unchanged
  bool drop_root = false;     ///< run as nobody when the tests run as root (permission tests)
};

/// Time a tool may run before wait_process kills it (s).
constexpr double kDefaultTimeoutSeconds = 120;

inline std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Starts `program` with `args`; standard input from `input_path` (empty: /dev/null).
inline pid_t spawn_process(const char* program, const std::vector<std::string>& args, const std::string& input_path,
                           const std::string& out_path, const std::string& err_path,
                           const ChildSetup& setup = {}) {
  std::vector<char*> argv{const_cast<char*>(program)};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    const int fi = open(input_path.empty() ? "/dev/null" : input_path.c_str(), O_RDONLY);
    const int fo = open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fi < 0 || fo < 0 || fe < 0 || dup2(fi, 0) < 0 || dup2(fo, 1) < 0 || dup2(fe, 2) < 0) _exit(127);
    if (setup.file_size_limit >= 0) {
      const rlimit limit{static_cast<rlim_t>(setup.file_size_limit), static_cast<rlim_t>(setup.file_size_limit)};
      if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(127);
    }
    if (setup.drop_root && geteuid() == 0 && (setgid(65534) != 0 || setuid(65534) != 0)) _exit(127);
    execv(program, argv.data());
    _exit(127);
  }
  return pid;
}

/// Waits for a spawned process, killing it after `timeout_seconds`, and collects (then removes)
/// its output files.
inline ProcessResult wait_process(pid_t pid, const std::string& out_path, const std::string& err_path,
                                  double timeout_seconds = kDefaultTimeoutSeconds) {
  ProcessResult r;
  int wstatus = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_seconds);
  pid_t done = 0;
  while (pid > 0 && (done = waitpid(pid, &wstatus, WNOHANG)) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      kill(pid, SIGKILL);
      r.timed_out = true;
      done = waitpid(pid, &wstatus, 0);
      break;
    }
    usleep(5000);
  }
  if (done == pid && WIFEXITED(wstatus)) r.status = WEXITSTATUS(wstatus);
  if (done == pid && WIFSIGNALED(wstatus) && !r.timed_out) r.signal = WTERMSIG(wstatus);
  r.out = read_file(out_path);
  r.err = read_file(err_path);
  std::remove(out_path.c_str());
  std::remove(err_path.c_str());
  return r;
}

/// Runs `program` with `args` and `input` as its standard input, and waits for it.
inline ProcessResult run_process(const char* program, const std::vector<std::string>& args,
                                 const std::string& input = "", const ChildSetup& setup = {},
                                 double timeout_seconds = kDefaultTimeoutSeconds) {
  static int serial = 0;
  const std::string base =
      ::testing::TempDir() + "/qtmv_cli_" + std::to_string(getpid()) + "_" + std::to_string(serial++);
  const std::string in = base + ".in", out = base + ".out", err = base + ".err";
  std::ofstream(in, std::ios::binary) << input;
  ProcessResult r = wait_process(spawn_process(program, args, in, out, err, setup), out, err, timeout_seconds);
  std::remove(in.c_str());
  return r;
}

}  // namespace qtmv::test
