// A child process the test owns: started with fork/exec, its stdout and stderr in a log file,
// signalled and reaped by its PID only. The destructor kills (SIGKILL) and reaps a child that is
// still running, so a failing test never leaves processes behind.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace tessera::test {

class Process {
 public:
  /// Starts argv[0] with `argv` (PATH not searched), output appended to `log`.
  Process(const std::vector<std::string>& argv, const std::filesystem::path& log) : mLog(log) {
    mPid = fork();
    if (mPid == 0) {
      const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
        close(fd);
      }
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
  }
  ~Process() {
    if (running()) {
      kill(mPid, SIGKILL);
      waitpid(mPid, nullptr, 0);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return mPid; }
  const std::filesystem::path& log() const { return mLog; }
  void signal(int sig) const {
    if (mPid > 0 && !mExit) kill(mPid, sig);
  }

  bool running() {
    if (mPid <= 0 || mExit) return false;
    int status = 0;
    if (waitpid(mPid, &status, WNOHANG) == mPid) {
      mExit = WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
      return false;
    }
    return true;
  }

  /// The exit code (negative: killed by that signal), or nullopt if it still runs after
  /// `timeout_s`.
  std::optional<int> wait(double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (running() && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (running()) return std::nullopt;
    return mExit;
  }

  std::string output() const {
    std::ifstream in(mLog);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  /// Waits until the log matches `pattern` (or the process ended, or `timeout_s` passed).
  bool waitFor(const std::string& pattern, double timeout_s) {
    const std::regex re(pattern);
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (std::regex_search(output(), re)) return true;
      if (!running()) return std::regex_search(output(), re);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }

 private:
  pid_t mPid = -1;
  std::optional<int> mExit;
  std::filesystem::path mLog;
};

}  // namespace tessera::test
