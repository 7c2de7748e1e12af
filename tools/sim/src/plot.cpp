// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/plot.hpp"

#include <spawn.h>
#include <sys/wait.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include <fmt/format.h>

#include "toonforce/sim/data_dir.hpp"

extern char** environ;

namespace toonforce {

namespace {
constexpr const char* kPython = "/usr/bin/python3";
}

std::string plot_script_path() {
  if (const char* env = std::getenv("TOONFORCE_PLOT_SCRIPT"); env != nullptr && *env != '\0') return env;
  if (const std::string installed = installed_data_dir(); !installed.empty()) {
    const std::string script = installed + "/plot_trace.py";
    std::error_code ec;
    if (std::filesystem::is_regular_file(script, ec)) return script;
  }
  return std::string(build_source_dir()) + "/tools/plot_trace.py";
}

Result<bool> plot_trace(const PlotRequest& request) {
  const std::string script = plot_script_path();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(script, ec)) {
    return Error{fmt::format("plot: the plotting script {} is missing (set TOONFORCE_PLOT_SCRIPT to "
                             "tools/plot_trace.py of a toonforce source tree)",
                             script)};
  }
  if (!std::filesystem::exists(kPython, ec)) {
    return Error{fmt::format("plot: {} is missing; install python3-matplotlib (tools/setup-deps does)", kPython)};
  }
  std::vector<std::string> args{kPython, script, "--kind", request.kind};
  if (!request.title.empty()) {
    args.emplace_back("--title");
    args.push_back(request.title);
  }
  args.insert(args.end(), request.extra_args.begin(), request.extra_args.end());
  args.push_back(request.trace_path);
  args.push_back(request.out_path);
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, kPython, nullptr, nullptr, argv.data(), environ);
  if (spawned != 0) return Error{fmt::format("plot: cannot start {}: {}", kPython, std::strerror(spawned))};
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return Error{fmt::format("plot: waiting for {} failed: {}", kPython, std::strerror(errno))};
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return Error{fmt::format("plot: {} failed (exit status {}); see its message above", script,
                             WIFEXITED(status) ? WEXITSTATUS(status) : -1)};
  }
  return true;
}

}  // namespace toonforce
