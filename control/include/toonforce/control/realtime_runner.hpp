// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The self-timed real-time runner behind `toonforce run` (Linux): a dedicated thread at
/// SCHED_FIFO where permitted, memory locked (mlockall), optionally pinned to a CPU, waking on
/// absolute deadlines (clock_nanosleep TIMER_ABSTIME on CLOCK_MONOTONIC, as cyclictest does).
/// Deadlines missed while the thread was late are skipped and counted, never bursted: after a
/// late wake-up the tick runs at the latest deadline that has passed, so its integer time (and
/// the loop's dt) tells the truth. Per tick it records wake-up latency, compute time and slack
/// in fixed histograms. A watchdog thread outside the loop commands zero force through
/// `EmergencyZero` when the loop's heartbeat stops for `watchdog_periods` periods.
///
/// The runner knows nothing of scenes: it drives a `PeriodicTask`. One tick is the task's
/// `tick(k)`; the runner measures around it, then calls `publish(k, timing)` (telemetry), and at
/// the end, or when `stop` becomes non-zero (a signal), `shutdown(k)`, which must command zero
/// force. A device clocked by its own servo thread (hal/device.hpp, Clocking::kDeviceThread)
/// runs the same task from that thread instead (`run_on_device`); `run_on_device` picks
/// the right one from the device's clocking, so a caller never needs to know the backend.

#include <signal.h>

#include <atomic>
#include <cstdint>
#include <span>
#include <string>

#include "toonforce/common/result.hpp"
#include "toonforce/control/latency_histogram.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

class PeriodicTask {
 public:
  virtual ~PeriodicTask() = default;
  /// One servo tick at integer time k (k increases; skipped deadlines make it jump).
  virtual void tick(std::int64_t k) noexcept = 0;
  /// After the tick, with its timing (outside the measured compute time).
  virtual void publish(std::int64_t k, const TickTiming& timing) noexcept = 0;
  /// The last call: command zero force now.
  virtual void shutdown(std::int64_t k) noexcept = 0;
};

/// Zero force from another thread or a signal handler, best effort (DeviceDriver::emergency_zero).
struct EmergencyZero {
  void (*zero)(void* context) noexcept = nullptr;
  void* context = nullptr;
  void operator()() const noexcept {
    if (zero != nullptr) zero(context);
  }
};

struct RealtimeOptions {
  double rate_hz = 1000.0;          ///< 500 .. 10000
  std::int64_t deadlines = 0;       ///< how many periods to run; 0: until stopped
  int priority = 80;                ///< SCHED_FIFO priority (1..99)
  int cpu = -1;                     ///< pin the servo thread to this CPU; -1: do not pin
  bool allow_non_realtime = false;  ///< run at normal priority when SCHED_FIFO is refused
  bool lock_memory = true;          ///< mlockall(MCL_CURRENT | MCL_FUTURE)
  std::int64_t watchdog_periods = 30;
  /// Where the heartbeat (the next tick's index) is stored; nullptr: a counter of the runner's
  /// own. `toonforce run` points it into the page it shares with its guardian process
  /// (tools/run/guardian.hpp), which watches it from outside this process: the same store
  /// per tick, no cost added.
  std::atomic<std::int64_t>* heartbeat = nullptr;
  /// Set to 1 by the servo thread right after its shut-down tick (zero force commanded), before
  /// the rest of the run winds down (the writer drains the telemetry to a reader that may be
  /// slow): a watcher outside the process then knows the loop ended, though the process goes
  /// on. nullptr: not kept.
  std::atomic<std::uint32_t>* ended = nullptr;
};

/// What the runner could set up, in words a person can act on.
struct RealtimeSetup {
  bool fifo = false;
  int priority = 0;
  bool memory_locked = false;
  int cpu = -1;
  std::string notes;  ///< one line per thing that was not as asked, with how to fix it
};

struct RunReport {
  RealtimeSetup setup;
  std::int64_t ticks = 0;           ///< ticks run
  std::int64_t missed = 0;          ///< deadlines skipped
  std::int64_t watchdog_trips = 0;  ///< heartbeat watchdog commanded zero force
  int stop_signal = 0;              ///< the signal that stopped the run, 0 if none
  double elapsed_s = 0.0;
  LatencyHistogram wake{1000, 20000};    ///< 1 us bins to 20 ms
  LatencyHistogram compute{100, 20000};  ///< 0.1 us bins to 2 ms
  LatencyHistogram slack{1000, 10000};   ///< 1 us bins to 10 ms; < 0 counted apart
};

/// Runs `task` until `options.deadlines` periods have passed or `stop` is non-zero (its value
/// is reported as the stop signal). Returns an error, before any tick, if the options are
/// invalid or SCHED_FIFO is refused and not allowed to go without it.
Result<RunReport> run_realtime(PeriodicTask& task, const RealtimeOptions& options, EmergencyZero emergency,
                               const std::atomic<int>& stop);

/// Runs `task` inside a self-clocked device's own servo thread (DeviceDriver::run_clocked), for
/// `options.deadlines` ticks (0: until `stop`). The device owns that thread's priority and
/// timing, so the report's "wake-up latency" is the jitter of its period (the time between
/// ticks minus the nominal period) and "missed" the periods it skipped. The same heartbeat
/// watchdog as run_realtime's watches it from outside.
Result<RunReport> run_device_clocked(PeriodicTask& task, DeviceDriver& device, const RealtimeOptions& options,
                                     const std::atomic<int>& stop);

/// run_realtime on the host's timer, or run_device_clocked, as `device` is clocked; the
/// watchdog's emergency zero is the device's.
Result<RunReport> run_on_device(PeriodicTask& task, DeviceDriver& device, const RealtimeOptions& options,
                                const std::atomic<int>& stop);

/// The advice printed when SCHED_FIFO is refused.
std::string realtime_permission_advice(int priority);

/// Every catchable signal whose default action would end the process (stop_signals(): SIGHUP,
/// SIGINT, SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGALRM, SIGXCPU, SIGXFSZ, ...) stores its number
/// in `stop` (async-signal-safe); a second one while the first is being handled calls
/// `emergency` and exits at once. SIGPIPE is ignored (a closed pipe is a write error). Fatal
/// signals (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP) call `emergency` (best
/// effort: it should be a single device write), then re-raise with the default action.
/// A SIGXFSZ the kernel sends for a file-size limit is ignored (the write fails with EFBIG);
/// one sent with kill() is a stop. `restore_signals()` puts back the stop signals' and
/// SIGPIPE's earlier actions and the fatal signals' default ones.
/// The handlers run on the thread's alternate signal stack (use_alternate_signal_stack()), so a
/// stack overflow, itself a SIGSEGV, still commands zero force; this installs one for the calling
/// thread, and every thread the runner and the session start installs its own.
void install_signal_handlers(std::atomic<int>& stop, EmergencyZero emergency);
/// The sigqueue() value with which `toonforce run`'s guardian passes on the first stop signal
/// it gets: if the loop process already stops for that same signal, it is the same stop (a
/// process-group kill reached both), not a second one.
inline constexpr int kGuardianFirstCopy = 0x74676331;
void restore_signals();
/// Gives the calling thread an alternate signal stack (64 KiB, mapped once per thread, before
/// its loop; released when the thread ends). Without one, a thread that overflowed its stack
/// died of SIGSEGV with no zero-force command: the handler had no stack to run on.
/// False if it could not be set up (the handler then runs on the thread's own stack).
bool use_alternate_signal_stack() noexcept;
/// Whether a SIGXFSZ is the kernel's for a file-size limit (`ulimit -f`), which every stop
/// handler ignores (the write fails with EFBIG and is reported as a full disk), rather than one
/// someone sent with kill(), which is a stop. The kernel sends it as if the process had: SI_USER
/// with the process's own pid. Async-signal-safe.
bool is_file_size_limit_signal(int signo, const siginfo_t* info) noexcept;
/// The signals install_signal_handlers() turns into a stop.
std::span<const int> stop_signals() noexcept;
/// "SIGHUP", "SIGINT", ... ("signal N" for a number without a name).
std::string signal_name(int signo);

}  // namespace toonforce
