// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Running the helper programs the reports need (valgrind, /usr/bin/python3), start-up code.

#include <chrono>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

/// Runs `argv` (argv[0] looked up in PATH) and waits; standard output goes to `stdout_path`
/// when not empty, and standard error too when `quiet_stderr`. The exit status, or an error
/// if it could not start or was killed by a signal.
Result<int> run_process(const std::vector<std::string>& argv, const std::string& stdout_path = {},
                        bool quiet_stderr = false);

/// Runs `argv` (argv[0] looked up in PATH) with its standard output into `stdout_path` and its
/// standard error into `stderr_path` (the same path for both: one file, in order), and waits at
/// most `timeout` (zero: no limit; past it the process is killed and this is an error). The exit
/// status, or an error if it could not start, was killed by a signal or timed out.
Result<int> run_captured(const std::vector<std::string>& argv, const std::string& stdout_path,
                         const std::string& stderr_path, std::chrono::milliseconds timeout = {});

/// The full path of `name` in PATH (or `name` itself if it holds a '/' and is executable);
/// empty if there is none.
std::string find_program(const std::string& name);

/// Quotes a command line for a person to read or paste into a shell.
std::string shell_line(const std::vector<std::string>& argv);

}  // namespace toonforce::report
