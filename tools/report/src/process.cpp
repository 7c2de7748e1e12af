// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/process.hpp"
#include "toonforce/report/staged_outputs.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <thread>

#include <fmt/format.h>

extern char** environ;

namespace toonforce::report {

namespace {

/// Starts `argv` with `actions` and waits for it, at most `timeout` when positive.
Result<int> spawn_and_wait(const std::vector<std::string>& argv, posix_spawn_file_actions_t& actions,
                           std::chrono::milliseconds timeout) {
  std::vector<std::string> args = argv;
  std::vector<char*> raw;
  for (auto& a : args) raw.push_back(a.data());
  raw.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, raw[0], &actions, nullptr, raw.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return Error{fmt::format("cannot start {}: {}", argv[0], std::strerror(spawned))};
  set_waited_child(pid);  // a stop signal kills it (staged_outputs.hpp)
  struct Forget {
    ~Forget() { set_waited_child(0); }
  } forget;
  int status = 0;
  if (timeout.count() > 0) {
    // Polled: the programs run here take a fraction of a second to minutes.
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const pid_t done = waitpid(pid, &status, WNOHANG);
      if (done == pid) break;
      if (done < 0 && errno != EINTR) {
        return Error{fmt::format("waiting for {} failed: {}", argv[0], std::strerror(errno))};
      }
      if (std::chrono::steady_clock::now() >= deadline) {
        kill(pid, SIGKILL);
        while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
        }
        return Error{fmt::format("{} did not finish within {:g} s and was stopped", argv[0],
                                 std::chrono::duration<double>(timeout).count())};
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  } else {
    while (waitpid(pid, &status, 0) < 0) {
      if (errno != EINTR) return Error{fmt::format("waiting for {} failed: {}", argv[0], std::strerror(errno))};
    }
  }
  if (!WIFEXITED(status)) return Error{fmt::format("{} was killed by signal {}", argv[0], WTERMSIG(status))};
  return WEXITSTATUS(status);
}

}  // namespace

Result<int> run_process(const std::vector<std::string>& argv, const std::string& stdout_path, bool quiet_stderr) {
  if (argv.empty()) return Error{"run_process: no command"};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!stdout_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, 1, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  if (quiet_stderr) posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  return spawn_and_wait(argv, actions, {});
}

Result<int> run_captured(const std::vector<std::string>& argv, const std::string& stdout_path,
                         const std::string& stderr_path, std::chrono::milliseconds timeout) {
  if (argv.empty()) return Error{"run_captured: no command"};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (stderr_path == stdout_path) {
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  } else {
    posix_spawn_file_actions_addopen(&actions, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  }
  return spawn_and_wait(argv, actions, timeout);
}

std::string find_program(const std::string& name) {
  if (name.empty()) return {};
  const auto runnable = [](const std::string& path) {
    std::error_code ec;
    return std::filesystem::is_regular_file(path, ec) && access(path.c_str(), X_OK) == 0;
  };
  if (name.find('/') != std::string::npos) return runnable(name) ? name : std::string();
  const char* path = std::getenv("PATH");
  std::string_view dirs = path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin";
  while (true) {
    const auto colon = dirs.find(':');
    const std::string_view dir = dirs.substr(0, colon);  // empty: the current directory
    const std::string candidate = (dir.empty() ? std::string(".") : std::string(dir)) + "/" + name;
    if (runnable(candidate)) return candidate;
    if (colon == std::string_view::npos) return {};
    dirs.remove_prefix(colon + 1);
  }
}

std::string shell_line(const std::vector<std::string>& argv) {
  std::string line;
  for (const auto& a : argv) {
    if (!line.empty()) line += ' ';
    const bool plain = !a.empty() && a.find_first_of(" \t'\"*?$\\|&;<>()[]{}~#") == std::string::npos;
    if (plain) {
      line += a;
    } else {
      line += '\'';
      for (const char c : a) {
        if (c == '\'') {
          line += "'\\''";
        } else {
          line += c;
        }
      }
      line += '\'';
    }
  }
  return line;
}

}  // namespace toonforce::report
