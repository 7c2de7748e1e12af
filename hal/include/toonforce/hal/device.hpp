// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The device seam (after modm's Bmi088Transport concept and libfranka's RobotControl): the
/// servo loop is a template over a `ServoDevice`, so the host simulation inlines in tests and
/// benchmarks; `DeviceDriver` is the one virtual interface for choosing a backend at run time,
/// and `DriverRef` adapts it to the concept (one indirect call each way per tick).
///
/// A device is clocked one of two ways (DeviceInfo::clocking): by the host's real-time timer,
/// which calls the loop's tick on absolute deadlines (control/realtime_runner.hpp), or by its
/// own servo thread (OpenHaptics' scheduler), which calls a tick function through
/// `DeviceDriver::run_clocked`. control/ runs both through this seam, never by knowing the backend.
///
/// Everything crosses the seam in the scene frame of effects.md §0 (x right, y away from the
/// user, z up, origin at the workspace centre) and SI units; each backend converts its own
/// frame. read() and write() are the tick's only system calls: no allocation, no exceptions.

#include <cstdint>
#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// The outcome of one device exchange. Anything but kOk means: command zero force this tick.
enum class DeviceStatus : std::uint8_t {
  kOk = 0,
  kNotReady,       ///< connected but not usable yet (not homed, not calibrated)
  kTimeout,        ///< no reply in time
  kDisconnected,   ///< unplugged or gone
  kProtocolError,  ///< a garbled or unexpected frame
  kDeviceFault,    ///< the device or its driver reported an error
};

constexpr std::string_view to_string(DeviceStatus s) noexcept {
  switch (s) {
    case DeviceStatus::kOk: return "ok";
    case DeviceStatus::kNotReady: return "not ready";
    case DeviceStatus::kTimeout: return "timeout";
    case DeviceStatus::kDisconnected: return "disconnected";
    case DeviceStatus::kProtocolError: return "protocol error";
    case DeviceStatus::kDeviceFault: return "device fault";
  }
  return "?";
}

/// One reading of the device, in scalar T: double at every backend of hal/; a device on a
/// fixed-point target reads in the loop's own scalar instead (see `device_scalar_t`).
template <class T>
struct BasicDeviceReading {
  Vec3<T> position_m;         ///< HIP position, scene frame [m]
  Vec3<T> velocity_m_per_s;   ///< valid when has_velocity
  bool has_velocity = false;  ///< the device measures velocity itself: no estimator runs
  std::uint32_t buttons = 0;  ///< bit i = button i pressed
  /// The device scaled the last force written before this reading down to what it can give
  /// (the Falcon: its +-4095 motor words saturated; the force kept its direction). Not a
  /// fault and not a reason to cut force: the loop may report it (telemetry, run summary,
  /// viewer). Backends that never scale a force leave it false.
  bool force_limited = false;
};
using DeviceReading = BasicDeviceReading<double>;

/// The scalar a device reads and is written in: double, unless the device type says
/// `using Scalar = ...;` (a microcontroller's device in the loop's Q16.16, so that no tick
/// converts through floating point: tools/mcu). A device in another scalar than double must
/// be in the loop's own.
template <class D>
struct DeviceScalarOf {
  using type = double;
};
// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class D>
  requires requires { typename D::Scalar; }
// clang-format on
struct DeviceScalarOf<D> {
  using type = typename D::Scalar;
};
template <class D>
using device_scalar_t = typename DeviceScalarOf<D>::type;

/// Who calls the servo loop's tick.
enum class Clocking : std::uint8_t {
  kHostTimer,     ///< the host's real-time timer (a thread of ours on absolute deadlines)
  kDeviceThread,  ///< the device's own servo thread (DeviceDriver::run_clocked)
};

/// The clock of one tick as a self-clocked device's servo thread sees it.
struct ClockedTick {
  std::int64_t tick = 0;  ///< periods since the run started, skipped periods included (Instant::tick)
  double dt_s = 0.0;      ///< [s] true time since the previous tick, as the device measures it
  double period_s = 0.0;  ///< [s] nominal period
};

enum class TickVerdict : std::uint8_t { kContinue, kStop };

/// The tick a self-clocked device calls in its servo thread: read() and write() of the device
/// are valid only inside it. Must not allocate, block or throw. kStop ends the run after this
/// tick (forces off).
using ClockedTickFn = TickVerdict (*)(void* context, const ClockedTick& clock) noexcept;

/// How a self-clocked run ended.
struct ClockedEnd {
  std::string device_stopped;  ///< why the device ended the run itself; empty when the tick did
};

/// What a device is and can do, known once it is open.
struct DeviceInfo {
  std::string name;  ///< for messages: "Novint Falcon (serial ...)"
  /// The largest force the backend commands [N]; each backend says what it is (the Falcon: what
  /// its motor words give in every direction at the workspace centre; the Omni: its cap).
  double max_force_n = 0.0;
  double max_continuous_force_n = 0.0;  ///< what the motors sustain (thermal model input)
  Vec3<double> workspace_min_m;         ///< scene frame
  Vec3<double> workspace_max_m;
  double nominal_rate_hz = 1000.0;
  Clocking clocking = Clocking::kHostTimer;
};

/// How a process other than the one driving the device commands zero force once that process
/// is gone (`toonforce run`'s guardian, docs/DEPLOY.md "Processes"): for a USB device, one
/// bulk-OUT transfer of `frame` on `endpoint` after claiming `interface` on the usbfs node
/// (the driving process's claim ends with it). Fixed-size: it lives in a shared page.
struct ExternalZero {
  enum class Kind : std::uint8_t {
    kNone,     ///< nothing outside the process can reach the device (the simulated one, the Omni)
    kUsbBulk,  ///< the Falcon: a zero-force frame over usbfs
  };
  Kind kind = Kind::kNone;
  char usbfs_node[64] = {};  ///< "/dev/bus/usb/BBB/DDD"
  std::uint8_t interface = 0;
  std::uint8_t endpoint = 0;
  std::uint8_t frame_bytes = 0;
  std::uint8_t frame[64] = {};
};

// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class D>
concept ServoDevice = requires(D& device, BasicDeviceReading<device_scalar_t<D>>& reading,
                               const Vec3<device_scalar_t<D>>& force_n) {
  { device.read(reading) } noexcept -> std::same_as<DeviceStatus>;
  { device.write(force_n) } noexcept -> std::same_as<DeviceStatus>;
};
// clang-format on

/// The run-time seam: one backend behind a virtual interface.
class DeviceDriver {
 public:
  virtual ~DeviceDriver() = default;
  DeviceDriver() = default;
  DeviceDriver(const DeviceDriver&) = delete;
  DeviceDriver& operator=(const DeviceDriver&) = delete;

  /// Reads the device for this tick.
  virtual DeviceStatus read(DeviceReading& reading) noexcept = 0;
  /// Commands a force [N] in the scene frame.
  virtual DeviceStatus write(const Vec3<double>& force_n) noexcept = 0;
  /// Commands zero force now, best effort, from any thread: the watchdog outside the servo
  /// thread and the fatal-signal path call it. Must not block indefinitely.
  virtual void emergency_zero() noexcept = 0;
  virtual const DeviceInfo& info() const noexcept = 0;
  /// What another process needs to zero the force once this one is gone (ExternalZero).
  virtual ExternalZero external_zero() const noexcept { return {}; }
  /// A person-readable explanation of the last non-ok status: what happened, what to do.
  virtual std::string last_error() const { return {}; }
  /// Clocking::kDeviceThread: runs `tick` in the device's own servo thread, every period,
  /// until it returns kStop or the device stops the run; blocks until then. Start-up and
  /// end-of-run code around the ticks may allocate; the ticks may not.
  virtual Result<ClockedEnd> run_clocked(ClockedTickFn tick, void* context) {
    static_cast<void>(tick);
    static_cast<void>(context);
    return Error{info().name + ": not a self-clocked device (its clocking is the host's timer)"};
  }
};

/// Adapts a DeviceDriver to the ServoDevice concept.
class DriverRef {
 public:
  explicit DriverRef(DeviceDriver& driver) noexcept : driver_(&driver) {}
  DeviceStatus read(DeviceReading& reading) noexcept { return driver_->read(reading); }
  DeviceStatus write(const Vec3<double>& force_n) noexcept { return driver_->write(force_n); }
  DeviceDriver& driver() const noexcept { return *driver_; }

 private:
  DeviceDriver* driver_;
};
static_assert(ServoDevice<DriverRef>);

}  // namespace toonforce
