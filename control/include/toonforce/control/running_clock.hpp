// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Time a watcher itself was running, for its stall checks (the heartbeat watchdog, the
/// guardian). A watcher polls: between two of its looks at the heartbeat, the monotonic clock
/// moves by its poll interval, plus its scheduling delay. When the watcher itself did not run
/// (its process stopped by job control, SIGSTOP, a frozen cgroup, a suspended virtual machine),
/// the clock moves by that whole time, and the process it watches was usually stopped with it:
/// counting that time against the watched loop kills a healthy loop after `fg`. So each step
/// counts at most `max_step_ns`; a longer step is time in which the watcher cannot tell what
/// the loop did, and counts as that much. The error is on the safe side of a real stall only
/// in that it is detected later, by at most the number of long steps times their excess, and
/// a real stall is still detected: a watcher that runs keeps counting.

#include <algorithm>
#include <cstdint>

namespace toonforce {

class RunningClock {
 public:
  /// `max_step_ns`: the longest step taken at its length (a few poll intervals).
  constexpr explicit RunningClock(std::int64_t max_step_ns) noexcept : max_step_ns_(max_step_ns) {}

  /// The watcher looked at `now_ns` (CLOCK_MONOTONIC); returns the running time counted since
  /// the last restart().
  constexpr std::int64_t look(std::int64_t now_ns) noexcept {
    if (started_) {
      const std::int64_t step = now_ns - last_ns_;
      elapsed_ns_ += std::clamp<std::int64_t>(step, 0, max_step_ns_);
      if (step > max_step_ns_) ++long_steps_;
    }
    started_ = true;
    last_ns_ = now_ns;
    return elapsed_ns_;
  }
  /// From now on, count from 0 (the heartbeat moved).
  constexpr void restart() noexcept { elapsed_ns_ = 0; }
  constexpr std::int64_t elapsed_ns() const noexcept { return elapsed_ns_; }
  /// Steps longer than max_step_ns so far (times the watcher did not run as it polls).
  constexpr std::int64_t long_steps() const noexcept { return long_steps_; }

 private:
  std::int64_t max_step_ns_;
  std::int64_t last_ns_ = 0;
  std::int64_t elapsed_ns_ = 0;
  std::int64_t long_steps_ = 0;
  bool started_ = false;
};

}  // namespace toonforce
