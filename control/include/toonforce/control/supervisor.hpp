// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The supervisor: the servo loop's first stage after the device read, a pure state machine
/// (no clock, no I/O: it is told the tick's inputs) that decides whether force may flow at all
/// this tick and returns that decision as a `Gate`.
///   - latches (until re-armed with their cause gone): an engaged e-stop; a gap of more than
///     `watchdog_periods` between ticks (missed deadlines, a stalled loop); `device_timeout`
///     failed device exchanges in a row (reads or writes);
///   - closes the gate for this tick: enable (deadman) released, the device not ready (homing,
///     calibrating), a failed read;
///   - says when the gate has just opened again (enabled, homed or re-armed), so the force must
///     engage afresh, and when a device error means the soft start must ramp again.
/// `NoSupervisor` is the gate of a loop without any of this (replay: effects.md §6 only).

#include <atomic>
#include <cstdint>

#include "toonforce/control/faults.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/hal/pins.hpp"

namespace toonforce {

/// What the loop is doing (the supervisor's modes, then the engage stage's).
enum class LoopState : std::uint8_t {
  kIdle = 0,  ///< enable released (or shut down): no force
  kHoming,    ///< the device is not ready yet (homing, calibrating): no force
  kEngaging,  ///< waiting for the scene force to drop below engage_force
  kRamping,   ///< soft start
  kActive,    ///< full force
  kFaulted,   ///< a latched fault: no force until re-armed
};

constexpr const char* to_string(LoopState s) noexcept {
  switch (s) {
    case LoopState::kIdle: return "idle";
    case LoopState::kHoming: return "homing";
    case LoopState::kEngaging: return "engaging";
    case LoopState::kRamping: return "ramping";
    case LoopState::kActive: return "active";
    case LoopState::kFaulted: return "faulted";
  }
  return "?";
}

/// The supervisor's decision for one tick.
struct Gate {
  /// kIdle, kHoming or kFaulted when closed by that; kActive when armed (the engage stage
  /// then says whether the loop is engaging, ramping or active).
  LoopState mode = LoopState::kActive;
  bool open = true;              ///< force may flow (armed and the device read succeeded)
  bool position = true;          ///< the read succeeded: there is a position to compute with
  bool reopened = false;         ///< armed again after idle, homing or a fault: engage afresh
  bool ramp_again_next = false;  ///< this tick's read failed: the soft start ramps again from the next tick
  bool ramp_again_now = false;   ///< the last tick's write failed: it ramps again from this tick
  FaultSet faults;               ///< this tick's (a device error), latched ones included
  bool rearm_refused = false;    ///< a re-arm was asked for while a latched cause persists
};

struct SupervisorConfig {
  std::int64_t watchdog_periods = 30;        ///< a larger gap between ticks latches kWatchdog
  std::int64_t device_timeout_periods = 10;  ///< this many failed exchanges in a row latch kDeviceSilent
};

class Supervisor {
 public:
  constexpr explicit Supervisor(const SupervisorConfig& config) noexcept : config_(config) {}
  /// A copy of a supervisor (a loop built at compile time, copied into place before it runs:
  /// tools/mcu) carries a pending re-arm over as a plain value.
  Supervisor(const Supervisor& other) noexcept
      : config_(other.config_),
        rearm_requests_(other.rearm_requests_.load(std::memory_order_relaxed)),
        rearm_seen_(other.rearm_seen_),
        latched_(other.latched_),
        mode_(other.mode_),
        was_armed_(other.was_armed_),
        armed_again_(other.armed_again_),
        write_failed_(other.write_failed_),
        started_(other.started_),
        steady_(other.steady_),
        failed_reads_(other.failed_reads_),
        failed_writes_(other.failed_writes_) {}
  Supervisor& operator=(const Supervisor&) = delete;

  /// The gate for a tick `gap` periods after the previous one.
  Gate admit(std::int64_t gap, PinLevel estop, PinLevel enable, DeviceStatus read) noexcept {
    // Re-arm requests are counted by the requester; one not seen yet is asked for. A plain
    // load: no exclusive-access retry loop in the tick (the exchange this replaced
    // was about 15 cycles of the bound), and requests made before this tick coalesce, as the
    // flag's did.
    const std::uint32_t requests = rearm_requests_.load(std::memory_order_relaxed);
    // The usual tick: armed, nothing asked, nothing wrong. Then the gate is simply open.
    // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
    // bound's path, and a side laid out of line costs it two taken branches (out and back).
    if (steady_ && read == DeviceStatus::kOk && estop == PinLevel::kInactive && enable == PinLevel::kActive &&
        gap <= config_.watchdog_periods && requests == rearm_seen_) [[unlikely]] {
      failed_reads_ = 0;
      return Gate{};
    }
    // The gate is built from locals and made once at the end: a `Gate g` first, then assigned,
    // was a copy of its 16 default bytes from flash (about 13 cycles of the tick's bound).
    bool rearm_refused = false;
    FaultSet faults{};
    LoopState mode = LoopState::kActive;
    const bool read_ok = read == DeviceStatus::kOk;
    const bool homing = read == DeviceStatus::kNotReady;
    const bool rearm = requests != rearm_seen_;
    rearm_seen_ = requests;
    if (rearm && latched_) {
      if (estop == PinLevel::kInactive && read_ok) {
        latched_ = FaultSet{};
        armed_again_ = true;
      } else {
        rearm_refused = true;
      }
    }
    if (estop != PinLevel::kInactive) latched_.set(Fault::kEstop);
    if (started_ && gap > config_.watchdog_periods) [[likely]]
      latched_.set(Fault::kWatchdog);
    started_ = true;
    if (read_ok || homing) {
      failed_reads_ = 0;
    } else {
      faults.set(Fault::kDeviceError);
      if (++failed_reads_ >= config_.device_timeout_periods) latched_.set(Fault::kDeviceSilent);
    }

    if (latched_) {
      mode = LoopState::kFaulted;
    } else if (enable != PinLevel::kActive) {
      mode = LoopState::kIdle;
    } else if (homing) {
      mode = LoopState::kHoming;
    }
    const bool armed = mode == LoopState::kActive;
    const bool reopened = armed && (!was_armed_ || armed_again_);
    was_armed_ = armed;
    armed_again_ = false;
    const bool open = armed && read_ok;
    const bool ramp_again_now = write_failed_;
    write_failed_ = false;
    mode_ = mode;
    // Steady from the next tick on when this one was open and clean (nothing latched, no
    // pending write failure): the fast path above then gives the same gate.
    steady_ = open && !rearm_refused && !latched_;
    return Gate{mode, open, read_ok, reopened, !read_ok, ramp_again_now, faults | latched_, rearm_refused};
  }

  /// The tick's write: failures count toward kDeviceSilent and make the soft start ramp again.
  /// A device that is not ready (homing, calibrating) refuses the force without failing, as
  /// its read says. Returns the faults it adds to this tick.
  FaultSet wrote(DeviceStatus write) noexcept {
    if (write == DeviceStatus::kOk || write == DeviceStatus::kNotReady) {
      failed_writes_ = 0;
      return {};
    }
    FaultSet f;
    f.set(Fault::kDeviceError);
    steady_ = false;
    if (++failed_writes_ >= config_.device_timeout_periods) {
      latched_.set(Fault::kDeviceSilent);
      mode_ = LoopState::kFaulted;
    }
    write_failed_ = true;
    return f | latched_;
  }

  /// Asks to clear the latched faults at the next tick (any thread: one atomic counter; the
  /// tick only reads it).
  void request_rearm() noexcept { rearm_requests_.fetch_add(1U, std::memory_order_relaxed); }
  /// The run is over: the loop is idle and must engage afresh if it ever runs again.
  void shut_down() noexcept {
    mode_ = LoopState::kIdle;
    was_armed_ = false;
    steady_ = false;
  }

  FaultSet latched() const noexcept { return latched_; }
  LoopState mode() const noexcept { return mode_; }

 private:
  SupervisorConfig config_;
  /// Re-arm requests made so far (wrapping: only a change is read) and the count the last
  /// tick saw. A request carries no data, so relaxed ordering is enough.
  std::atomic<std::uint32_t> rearm_requests_{0};
  std::uint32_t rearm_seen_ = 0;
  FaultSet latched_;
  LoopState mode_ = LoopState::kActive;
  bool was_armed_ = true;  ///< the loop starts armed, engaging (a first tick is no re-opening)
  bool armed_again_ = false;
  bool write_failed_ = false;
  bool started_ = false;
  bool steady_ = false;  ///< the last tick's gate was open and clean: the fast path applies
  std::int64_t failed_reads_ = 0;
  std::int64_t failed_writes_ = 0;
};

/// No supervision: the gate is always open (replay of a recorded motion; effects.md §6 only).
class NoSupervisor {
 public:
  constexpr explicit NoSupervisor(const SupervisorConfig&) noexcept {}
  Gate admit(std::int64_t, PinLevel, PinLevel, DeviceStatus read) noexcept {
    Gate g;
    g.position = g.open = read == DeviceStatus::kOk;
    if (!g.open) g.faults.set(Fault::kDeviceError);
    return g;
  }
  FaultSet wrote(DeviceStatus write) noexcept {
    FaultSet f;
    if (write != DeviceStatus::kOk) f.set(Fault::kDeviceError);
    return f;
  }
  void request_rearm() noexcept {}
  void shut_down() noexcept {}
  FaultSet latched() const noexcept { return {}; }
  LoopState mode() const noexcept { return LoopState::kActive; }
};

}  // namespace toonforce
