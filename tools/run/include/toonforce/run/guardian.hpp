#pragma once
/// `toonforce run`'s guardian (issue 28; docs/DEPLOY.md "Processes"). `run` forks before it does
/// anything else: the child is the loop process (scene, device, servo loop, viewer, everything
/// `run` did before); the parent, the guardian, holds what stops the force from outside it and
/// does nothing else. It parses nothing, starts no thread, and watches the loop process through
/// a pidfd (its end, whatever ended it: SIGKILL, a crash, the OOM killer) and a heartbeat in a
/// page both share (a stall past its limit: it kills the loop process). When the loop process
/// ends before its loop did, the guardian commands zero force at once: on a Falcon it claims the
/// USB interface the dead process held and sends the zero-force frame; with an amplifier-enable
/// line it drops the line (it alone holds it, active only while the loop ticks). Then it ends
/// the trace with that zero-force row, says what happened and exits with status 3.
///
/// The other way round, the loop process watches its guardian (PR_SET_PDEATHSIG): if the
/// guardian dies, the loop process gets SIGTERM, stops with zero force and says so.
///
/// The shared page is written by the loop process at no cost to the tick: the runner's
/// heartbeat lives in it (RealtimeOptions::heartbeat), and the writer thread copies each frame
/// it takes there (a sequence lock). Stop signals the guardian gets it passes on with
/// sigqueue(); the first marked kGuardianFirstCopy (realtime_runner.hpp), so that a signal sent
/// to both processes (Ctrl-C at a terminal reaches both and is not passed on; a service
/// manager's SIGTERM to the whole group) still stops the loop once, with its summary.

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <string>

#include "toonforce/control/telemetry.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce::guardian {

/// How far the loop process got; the guardian acts on the end of a loop that had not ended.
enum class Phase : std::uint32_t {
  kStarting = 0,    ///< scene, options: no device yet
  kDeviceOpen = 1,  ///< the device is open (its ExternalZero is in the page); the loop may tick
  kLoopEnded = 2,   ///< the loop ended on its own and commanded zero force (its shutdown tick)
};

/// The page the loop process and its guardian share (MAP_SHARED, mapped before the fork).
struct SharedPage {
  std::atomic<std::int64_t> heartbeat{0};  ///< the runner's: the next tick's index; 0 before the first
  std::atomic<std::uint32_t> phase{0};     ///< Phase
  pid_t guardian_pid = 0;
  std::int64_t period_ns = 0;              ///< the loop's period, set before kDeviceOpen
  ExternalZero zero;                       ///< set before kDeviceOpen
  std::atomic<std::uint32_t> frame_seq{0}; ///< odd while `frame` is being written
  TelemetryFrame frame{};                  ///< the last frame the writer thread took
  std::atomic<std::uint64_t> frames{0};    ///< frames the writer took
  std::atomic<std::uint64_t> trace_flushed_rows{0};  ///< rows the trace file holds for sure
};
static_assert(std::atomic<std::int64_t>::is_always_lock_free && std::atomic<std::uint32_t>::is_always_lock_free,
              "the page is shared between processes: its atomics must be lock-free");

/// A zero-filled page shared with the children forked after it; nullptr on failure (errno).
SharedPage* map_shared_page() noexcept;

/// Loop process, writer thread: the frame it just took.
void publish_frame(SharedPage& page, const TelemetryFrame& frame) noexcept;
/// Guardian: the last frame published, if any (a copy that was not being written).
bool read_frame(const SharedPage& page, TelemetryFrame& out) noexcept;

/// An output line the guardian drives (the amplifier enable): active while the loop ticks.
class EnableLine {
 public:
  virtual ~EnableLine() = default;
  /// False when the line could not be set.
  virtual bool set(bool active) noexcept = 0;
  virtual std::string describe() const = 0;  ///< "gpiochip0 line 5 (--amp-enable-pin)"
};

struct GuardOptions {
  /// No tick for this long while the loop runs: the guardian kills the loop process. Longer
  /// than the in-process heartbeat watchdog (which zeroes first), so it acts on a process
  /// that is stopped or wedged as a whole.
  std::int64_t stall_limit_ns = 500'000'000;
  EnableLine* enable = nullptr;  ///< may be null
};

/// What the guardian saw and did.
struct GuardOutcome {
  int wait_status = 0;          ///< waitpid's status of the loop process
  bool loop_died = false;       ///< it ended while its loop had not (signal, crash, stall, early exit)
  bool stalled = false;         ///< the guardian killed it for a stalled heartbeat
  std::string cause;            ///< "killed by SIGKILL", "stalled: no tick for 512 ms, killed by the guardian", ...
  Phase phase = Phase::kStarting;  ///< the phase it ended in
  std::int64_t ticks = 0;       ///< the heartbeat at the end
  std::int64_t death_ns = 0;    ///< CLOCK_MONOTONIC when the guardian saw the end
  std::int64_t zero_ns = 0;     ///< when the zero command had been sent (0: none)
  bool zero_sent = false;
  std::string zero_detail;      ///< what was done to zero the force, or why nothing could be
  bool have_frame = false;
  TelemetryFrame last_frame{};  ///< the last frame the writer took
  double t_end_s = 0.0;         ///< the loop's time at the zero command (see guard())
  std::string warnings;         ///< said during the run (e.g. the USB node could not be opened)
};

/// Watches `loop` (a child of this process) until it ends, passing stop signals on to it, and
/// zeroes the force if it ended while its device was open and its loop had not ended. The loop's time at the zero command is the last heartbeat's tick time plus the time
/// since the guardian saw that heartbeat (to within one poll, 1 ms).
GuardOutcome guard(pid_t loop, SharedPage& page, const GuardOptions& options);

/// The trace's end after a death: cut back to its last whole row, then one row at the zero
/// command's time with zero force (the last frame's position and state). An error in words.
std::string end_trace(const std::string& path, const GuardOutcome& outcome, std::size_t effect_values);

/// A child's waitpid() status in words: "killed by SIGKILL (core dumped)", "exited with status 2".
std::string describe_wait_status(int status);

/// What the guardian says on standard error after a death (several lines).
std::string describe_outcome(const GuardOutcome& outcome, pid_t loop);

/// The statistics JSON the guardian writes when the loop process died before writing its own.
std::string outcome_json(const GuardOutcome& outcome, pid_t loop);

/// The exit status of `toonforce run` when the loop process died and the guardian zeroed the
/// force (docs/spec/exits.md).
inline constexpr int kExitLoopDied = 3;

}  // namespace toonforce::guardian
