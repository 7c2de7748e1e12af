// SPDX-License-Identifier: Apache-2.0
#pragma once
// Runs the toonforce executable built with the tests (TOONFORCE_BINARY) and captures what it
// prints; a child inherits umockdev's preload and testbed, so it sees the emulated devices.
#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace toonforce::test {

struct CommandRun {
  int status = -1;     ///< exit status, -1 if it did not exit normally
  std::string output;  ///< stdout and stderr
};

inline CommandRun run_toonforce(const std::string& args) {
  CommandRun r;
  FILE* p = ::popen((std::string(TOONFORCE_BINARY) + " " + args + " 2>&1").c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int status = ::pclose(p);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace toonforce::test
