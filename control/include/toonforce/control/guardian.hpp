// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce run`'s guardian: a program of its own (`toonforce-guardian`, guardian_main.cpp)
/// that holds what stops the force from outside the loop's process, and nothing else. `run`
/// forks before it does anything else (process_split.hpp): the child is the loop's process
/// (scene, device, servo loop, server); the parent execs this program, which links no parser,
/// no network and no report code, so that what it does is what this file says.
///
/// It watches the loop's process through a pidfd (its end, whatever ended it: SIGKILL, a crash,
/// the OOM killer; the pidfd's wait status is the truth of how it ended) and a heartbeat in a
/// page both share (a stall past its limit, in time the guardian itself ran: it kills the loop's
/// process). When the loop's process ends while its loop runs, or by a signal at any time after
/// its device was open, the guardian commands zero force at once: on a Falcon it claims the USB
/// interface the dead process held and sends the zero-force frame, through a usbfs node it
/// opened and verified itself (a Falcon's bus and device numbers, its vendor and product in
/// sysfs, the node's device number); with an amplifier-enable line it drops the line (it alone
/// holds it, active only while the loop ticks). Then it hands over to `toonforce`'s epilogue
/// (which may fail without harm: it writes the trace's zero-force row and the statistics, and
/// says what happened) and the command exits with status 3.
///
/// Only the loop's process writes the page: the server process, which parses what the network
/// sends, is forked by the loop's process and drops the page before it runs (server_process).
/// Even so, nothing in the page decides alone whether the force is zeroed: the device's node is
/// verified, and a death by a signal is zeroed whatever the page says.
///
/// The other way round, the loop's process watches its guardian (PR_SET_PDEATHSIG): if the
/// guardian dies, the loop's process gets SIGTERM, stops with zero force and says so; a second
/// parent-death signal, SIGCONT from another of its threads, continues it if it was stopped, so
/// that a stopped loop whose guardian died does not stay behind holding the device.

#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

#include "toonforce/control/telemetry.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce::guardian {

/// How far the loop's process got.
enum class Phase : std::uint32_t {
  kStarting = 0,    ///< scene, options: no device yet
  kDeviceOpen = 1,  ///< the device is open (its ExternalZero is in the page); the loop may tick
};

/// What the guardian found and did, for the epilogue (written into the page by the guardian
/// once the loop's process has ended; fixed-size text, no pointer).
struct Verdict {
  std::int32_t loop_pid = 0;
  std::int32_t wait_status = 0;
  std::int32_t exit_status = 0;  ///< the command's
  std::uint8_t stalled = 0;
  std::uint8_t zero_sent = 0;
  std::uint8_t loop_ended = 0;
  std::int64_t ticks = 0;
  std::int64_t death_ns = 0;
  std::int64_t zero_ns = 0;
  double t_end_s = 0.0;
  char cause[160] = {};
  char zero_detail[480] = {};
};

/// The most devices whose force the guardian zeroes (a world's devices: control/world.hpp).
inline constexpr std::size_t kMaxGuardedDevices = 4;

/// The page the loop's process and its guardian share (a memfd, mapped before the fork).
struct SharedPage {
  std::atomic<std::int64_t> heartbeat{0};    ///< the runner's: the next tick's index; 0 before the first
  std::atomic<std::uint32_t> phase{0};       ///< Phase
  std::atomic<std::uint32_t> loop_ended{0};  ///< the runner's: 1 after the shut-down tick (RealtimeOptions::ended)
  /// The guardian's: 1 once it watches (the loop's process opens its device only then), 2 if it
  /// cannot (the loop's process ends without opening it).
  std::atomic<std::uint32_t> guardian_ready{0};
  pid_t guardian_pid = 0;
  std::int64_t period_ns = 0;  ///< the loop's period, set before kDeviceOpen
  /// Each device's, set before kDeviceOpen: the first `zero_count` (one device: one; a world:
  /// one per device). The guardian reads no more than kMaxGuardedDevices whatever the count says.
  std::array<ExternalZero, kMaxGuardedDevices> zeros{};
  std::uint32_t zero_count = 0;
  std::atomic<std::uint32_t> frame_seq{0};  ///< odd while `frame` is being written
  TelemetryFrame frame{};                   ///< the last frame the writer thread took
  std::atomic<std::uint64_t> frames{0};     ///< frames the writer took
  Verdict verdict{};                        ///< the guardian's, after the loop's process ended
};
static_assert(std::atomic<std::int64_t>::is_always_lock_free && std::atomic<std::uint32_t>::is_always_lock_free,
              "the page is shared between processes: its atomics must be lock-free");

/// The page in a new memfd named "toonforce-guardian" (so /proc/PID/maps names it), mapped and
/// zero-filled; `fd` receives the memfd (close-on-exec) or -1. nullptr on failure (errno).
SharedPage* create_shared_page(int& fd) noexcept;
/// The same, the descriptor closed: a page shared with the children forked after it.
SharedPage* map_shared_page() noexcept;
/// The page of a memfd made by create_shared_page (another process's): nullptr if `fd` is not
/// one of that size.
SharedPage* attach_shared_page(int fd) noexcept;
void unmap_shared_page(SharedPage* page) noexcept;

/// Loop's process, writer thread: the frame it just took.
void publish_frame(SharedPage& page, const TelemetryFrame& frame) noexcept;
/// The last frame published, if any (a copy that was not being written).
bool read_frame(const SharedPage& page, TelemetryFrame& out) noexcept;

/// An output line the guardian drives (the amplifier enable): active while the loop ticks.
class EnableLine {
 public:
  virtual ~EnableLine() = default;
  /// False when the line could not be set.
  virtual bool set(bool active) noexcept = 0;
  virtual std::string describe() const = 0;  ///< "the amplifier-enable line /dev/gpiochip0 line 5"
};

/// The guardian's own enable line: requested through the GPIO character device (uAPI v1, the
/// interface libgpiod 1.6 uses) by the guardian itself, at its inactive level.
class GpioEnableLine final : public EnableLine {
 public:
  /// `chip`: /dev/gpiochipN (a character device that answers as a GPIO chip). An error in
  /// words, or "" with the line requested.
  std::string open(const std::string& chip, std::uint32_t offset, bool active_low);
  ~GpioEnableLine() override;
  bool set(bool active) noexcept override;
  std::string describe() const override;

 private:
  int handle_ = -1;
  std::string chip_;
  std::uint32_t offset_ = 0;
};

struct GuardOptions {
  /// No tick for this long, counted in time the guardian itself ran (running_clock.hpp), while
  /// the loop runs: the guardian kills the loop's process. Longer than the in-process heartbeat
  /// watchdog (which zeroes first), so it acts on a process that is stopped or wedged as a whole.
  std::int64_t stall_limit_ns = 500'000'000;
  EnableLine* enable = nullptr;  ///< may be null
  bool quiet_warnings = false;   ///< do not print warnings as they come (tests)
  /// Unblock the stop signals once the handlers that pass them on are in place (the program:
  /// `run` blocks them before it forks, so that none is lost or takes its default action).
  bool unblock_stop_signals = false;
};

/// What the guardian saw and did.
struct GuardOutcome {
  int wait_status = 0;            ///< waitpid's status of the loop's process
  bool device_seen_open = false;  ///< the page said kDeviceOpen at some time
  bool loop_ended = false;        ///< the page said the loop's shut-down tick was done
  bool loop_died = false;         ///< ended while the device was open and its loop had not ended, or by a signal
  bool stalled = false;           ///< the guardian killed it for a stalled heartbeat
  std::string cause;              ///< "killed by SIGKILL", "stalled: no tick for 512 ms, ...", ...
  std::int64_t ticks = 0;         ///< the heartbeat at the end
  std::int64_t death_ns = 0;      ///< CLOCK_MONOTONIC when the guardian saw the end
  std::int64_t zero_ns = 0;       ///< when the zero command had been sent (0: none)
  bool zero_sent = false;
  std::string zero_detail;  ///< what was done to zero the force, or why nothing could be
  bool have_frame = false;
  TelemetryFrame last_frame{};  ///< the last frame the writer took
  double t_end_s = 0.0;         ///< the loop's time at the zero command (see guard())
  std::string warnings;         ///< said during the run (e.g. the USB node could not be opened)
};

/// Watches `loop` (a child of this process) until it ends, passing stop signals on to it, and
/// zeroes the force if it ended while its device was open and its loop had not ended, or by a
/// signal after its device was open. The loop's time at the zero command is the last
/// heartbeat's tick time plus the time since the guardian saw that heartbeat (to within one
/// poll, 1 ms).
GuardOutcome guard(pid_t loop, SharedPage& page, const GuardOptions& options);

/// The Falcon's usbfs node for `zero` (its "/dev/bus/usb/BBB/DDD"), opened read-write only if
/// it is what it says: the path has exactly that form, the node is the USB device character
/// device of that bus and address, and sysfs gives that device a Falcon's vendor and product
/// (0403:cb48). The descriptor, or -1 with `why` said.
int open_verified_usbfs(const ExternalZero& zero, std::string& why);

/// A child's waitpid() status in words: "killed by SIGKILL (core dumped)", "exited with status 2".
std::string describe_wait_status(int status);

/// The exit status of `toonforce run` when the loop's process died and the guardian zeroed the
/// force (docs/spec/exits.md).
inline constexpr int kExitLoopDied = 3;

/// The verdict of `outcome` as the epilogue reads it (fixed-size text, cut to fit).
Verdict make_verdict(const GuardOutcome& outcome, pid_t loop, int exit_status) noexcept;

}  // namespace toonforce::guardian
