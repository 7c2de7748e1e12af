// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce run`'s process split (docs/DEPLOY.md "Processes"): the first thing `run` does is
/// fork. The child goes on as the loop's process (scene, device, servo loop, the server process
/// it forks in turn); the parent execs the guardian program (guardian.hpp), so the guardian
/// carries none of `run`'s code: no parser, no network, no report.
///
/// The stop signals are blocked across the fork and the exec: the guardian lets them through once
/// its handlers pass them on, the loop's process once its own are in place
/// (unblock_stop_signals), so a signal in the first milliseconds is neither lost nor a death by
/// its default action.

#include <sys/types.h>

#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/control/guardian.hpp"

namespace toonforce {

struct GuardianStart {
  std::string program;                ///< the guardian's path (guardian_program_path())
  std::vector<std::string> epilogue;  ///< what it execs after a death ("--page-fd N" appended)
  double stall_limit_ms = 500.0;
  int priority = 0;         ///< SCHED_FIFO priority of the guardian (0: normal)
  std::string enable_chip;  ///< the amplifier-enable line, if any: /dev/gpiochipN
  unsigned enable_offset = 0;
  bool enable_active_low = false;
};

/// `toonforce-guardian` beside the running program (a build tree's bin/), else in
/// ../libexec/toonforce/ from it (an install); an error in words if neither is executable.
Result<std::string> guardian_program_path();

/// Forks. Returns in the child (the loop's process) with the page it shares with the guardian
/// (PR_SET_PDEATHSIG set: SIGTERM, and SIGCONT from a thread of its own, so a stopped loop is
/// continued to see it); the stop signals are still blocked there. In the parent it execs the
/// guardian and never returns; if the exec fails, it stops the child, says why and exits 2. An
/// error (before the fork) in words.
Result<guardian::SharedPage*> split_off_guardian(const GuardianStart& start);

/// The loop's process, once its stop handlers are in place: lets the blocked signals through.
void unblock_stop_signals() noexcept;

/// The loop's process, before it opens its device: until the guardian watches (true), or it
/// said it cannot or did not within `timeout_s` (false).
bool wait_for_guardian(const guardian::SharedPage& page, double timeout_s) noexcept;

}  // namespace toonforce
