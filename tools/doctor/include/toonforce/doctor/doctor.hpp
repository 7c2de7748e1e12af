// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce doctor`: what decides real-time behaviour on this host, each with its finding and
/// its fix. Everything is read through a root directory (default "/") so tests point it at a
/// faked /sys, /proc and /dev tree: the kernel, the limits and capabilities of this process
/// (/proc/self/limits, /proc/self/status), RT throttling, CPU governors, isolated CPUs, the
/// clock source, the device nodes of each backend with this user's permission on them, and an
/// OpenHaptics install (hal/omni install_check.hpp: /usr/lib64, libraw1394.so.8, GTDD_HOME).
/// Given a world scene's devices, the Falcons are checked per device instead: the one its
/// `select` serial names (sysfs `serial`), that node's permission, each line naming the device.

#include <optional>
#include <string>
#include <vector>

namespace toonforce {

enum class Verdict { kOk, kInfo, kWarn, kFail };

struct Finding {
  std::string check;  ///< "kernel", "SCHED_FIFO", ...
  Verdict verdict = Verdict::kOk;
  std::string finding;  ///< what was found
  std::string fix;      ///< what to do (empty when nothing)
};

/// One `[[device]]` of a world scene (`doctor --scene`): after the host's checks, each gets its
/// own, named after it (spec interfaces.md "toonforce doctor").
struct DoctorWorldDevice {
  std::string name;
  std::string backend = "sim";  ///< "sim", "falcon" or "omni"
  std::string select;           ///< a Falcon's serial number, an OpenHaptics device name; empty: the only one
};

struct DoctorOptions {
  std::string root = "/";   ///< where sys/, proc/ and dev/ are
  int priority = 80;        ///< the SCHED_FIFO priority `toonforce run` asks for
  bool check_clock = true;  ///< clock_getres of this host (not part of the root tree)
  /// $GTDD_HOME of the environment the loop will run in (the Touch driver's configuration);
  /// nullopt: unset. The command passes its own.
  std::optional<std::string> gtdd_home;
  /// The devices of a world scene; empty: every attached device is checked as the host's.
  std::vector<DoctorWorldDevice> world;
};

std::vector<Finding> run_doctor(const DoctorOptions& options);

/// The host is ready when nothing failed.
bool host_ready(const std::vector<Finding>& findings);

/// The report for a person, one check per line with its fix underneath.
std::string format_findings(const std::vector<Finding>& findings);

}  // namespace toonforce
