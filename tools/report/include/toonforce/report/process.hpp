#pragma once
/// Running the helper programs the reports need (valgrind, /usr/bin/python3), start-up code.

#include <string>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

/// Runs `argv` (argv[0] looked up in PATH) and waits; standard output goes to `stdout_path`
/// when not empty, and standard error too when `quiet_stderr`. The exit status, or an error
/// if it could not start or was killed by a signal.
Result<int> run_process(const std::vector<std::string>& argv, const std::string& stdout_path = {},
                        bool quiet_stderr = false);

/// Quotes a command line for a person to read or paste into a shell.
std::string shell_line(const std::vector<std::string>& argv);

}  // namespace toonforce::report
