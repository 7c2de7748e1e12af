// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What a measured figure depends on besides the code: the machine, its load while measuring,
/// the compiler. Reports print it beside every table of times.

#include <string>

namespace toonforce::report {

struct MachineInfo {
  std::string cpu;       ///< /proc/cpuinfo model name
  int cpus = 0;          ///< online CPUs
  std::string kernel;    ///< uname -r
  std::string compiler;  ///< of this build
  std::string date_utc;  ///< when measured, YYYY-MM-DD HH:MM
};

MachineInfo machine_info();
/// The 1, 5 and 15 minute load averages (/proc/loadavg), "1.23 2.34 3.45".
std::string load_average();
/// "CPU, N vCPUs, kernel K, compiler C".
std::string describe(const MachineInfo& m);

}  // namespace toonforce::report
