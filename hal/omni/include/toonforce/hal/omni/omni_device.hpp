// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Phantom Omni / 3D Systems Touch through OpenHaptics' HD library, loaded at run time
/// (docs/OMNI.md). The device is clocked by the vendor: OpenHaptics' scheduler owns
/// the servo thread and calls our frame every tick; inside it, between hdBeginFrame and
/// hdEndFrame, the frame calls one plain tick function (a function pointer and a context: no
/// std::function, no allocation), which uses read() and write() of this DeviceDriver as any
/// servo loop does. Other threads talk to the loop only through lock-free buffers: status()
/// (a sequence lock written each tick) and atomic requests (emergency_zero, request_stop).
///
///   auto omni = open_omni({});                 // load libHD, init, read limits, calibrate
///   omni.value()->start(&my_tick, &my_loop);   // my_tick(ctx, clock) runs in the servo thread
///   ... omni.value()->stop();                  // forces off, scheduler stopped
///
/// Safety owned here (the loop may add more, never less):
///  - forces stay off (hdDisable(HD_FORCE_OUTPUT), zero commanded) until hdCheckCalibration
///    says OK, then ramp in from zero; read() says kNotReady until then;
///  - the commanded force never exceeds the cap: HD_NOMINAL_MAX_CONTINUOUS_FORCE by default,
///    OmniOptions::max_force_n if given (at most HD_NOMINAL_MAX_FORCE, the peak), read from the
///    device at open time, never hard-coded (OMNI.md §3);
///  - HD errors map onto the fault model of hd_errors.hpp: force errors hold zero force, then
///    ramp back (read() says kNotReady while held); every other error stops the loop: zero
///    force, forces disabled, the callback unscheduled, last_error() naming the HD error;
///  - scheduler overruns are counted, passed on as dt, and stop the loop when too many follow
///    one another.
/// Positions are in the scene frame in metres (omni_frame.hpp). Units and frames of everything
/// else are in the field comments.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/hal/omni/hd_api.hpp"
#include "toonforce/hal/omni/omni_frame.hpp"
#include "toonforce/hal/omni/seqlock.hpp"

namespace toonforce {

namespace hd {
class Library;
}

struct OmniOptions {
  /// OpenHaptics device name as configured with Touch_Setup ("Default Device"); empty:
  /// HD_DEFAULT_DEVICE. Users report that an explicit name fixes "failed to initialize"
  /// (OMNI.md §5). Several devices in one process: each its own name.
  std::string device_name;
  /// The libHD file to load; empty: $TOONFORCE_LIBHD, else libHD.so, libHD.so.3.4, libHD.so.3.0
  /// through the dynamic loader (hd_library.hpp).
  std::string library_path;
  /// [Hz] the vendor scheduler's rate; the reference guide lists 500, 1000 and 1600 (FireWire)
  /// and warns that lower rates cause instability (OMNI.md §2.2).
  double scheduler_rate_hz = 1000.0;
  /// [N] the force cap. 0: the device's HD_NOMINAL_MAX_CONTINUOUS_FORCE, what its motors
  /// sustain (public drivers cap well below the peak: sawSensablePhantom at 2 N, OMNI.md §3),
  /// or the peak HD_NOMINAL_MAX_FORCE if it reports no continuous force. > 0: this value, at
  /// most the peak; raise it above the continuous force for short bursts (the library's thermal
  /// model then answers HD_WARM_MOTORS, which holds force at zero until the motors cool).
  double max_force_n = 0.0;
  /// [s] forces ramp 0 -> 1 over this time once calibration is OK.
  double enable_ramp_s = 0.5;
  /// [s] after a force error, force is held at zero this long, then ramps back ...
  double force_error_hold_s = 0.1;
  /// [s] ... over this time.
  double recovery_ramp_s = 1.0;
  /// [s] after HD_WARM_MOTORS, the hold lasts at least this long, and while the motor
  /// temperature model reads above warm_motors_resume_temperature.
  double warm_motors_hold_s = 2.0;
  /// [0..1] HD_MOTOR_TEMPERATURE below which a warm-motors hold may end (when the device has it).
  double warm_motors_resume_temperature = 0.8;
  /// [s] how often hdCheckCalibration runs inside the loop (before and after it is OK: the
  /// guide recommends periodic checks for auto-calibrating devices, OMNI.md §2.2).
  double calibration_check_period_s = 0.1;
  /// [s] how often the motor temperature model is read.
  double temperature_period_s = 0.1;
  /// Stop when this many ticks in a row overran their period (skipped periods or a callback
  /// longer than one period).
  int max_consecutive_overruns = 20;
  /// Pass HD_CURRENT_VELOCITY (smoothed by the library) as the measured velocity. Off by
  /// default: the library's filter is not documented (OMNI.md §2.2), so the controller's own
  /// estimator (spec effects.md §0, cutoff from the scene) is used, as on the host
  /// simulation's Omni preset, and the same scene behaves the same on both.
  bool use_device_velocity = false;
  /// Devices calibrated by encoder reset only: reset at open, with the arm in its reset pose
  /// (as OpenHaptics' calibration example does).
  bool encoder_reset_at_open = true;
  /// Call hdDisableDevice when the device is closed. Unset: yes, except on the FireWire stack
  /// (is_firewire_stack), where sawSensablePhantom found it crashes FireWire Omnis and never
  /// calls it; the scheduler is stopped and forces are off before either way.
  std::optional<bool> disable_device_on_close;
  /// Workspace centre in the device frame [mm]; unset: the centre of
  /// HD_USABLE_WORKSPACE_DIMENSIONS (omni_frame.hpp).
  std::optional<Vec3<double>> workspace_centre_mm;
};

/// What the device says about itself at open time, converted to SI and the scene frame.
/// Zero means "the device does not report it" unless noted.
struct OmniLimits {
  double max_force_n = 0.0;                           ///< HD_NOMINAL_MAX_FORCE (peak, room temperature); > 0
  double max_continuous_force_n = 0.0;                ///< HD_NOMINAL_MAX_CONTINUOUS_FORCE
  double max_stiffness_n_per_m = 0.0;                 ///< HD_NOMINAL_MAX_STIFFNESS [N/mm] * 1000
  double max_damping_n_s_per_m = 0.0;                 ///< HD_NOMINAL_MAX_DAMPING [N s/mm] * 1000
  double force_cap_n = 0.0;                           ///< what this device enforces (OmniOptions::max_force_n)
  std::string force_cap_source;                       ///< where force_cap_n comes from, for messages
  double software_velocity_limit_m_per_s = 0.0;       ///< HD_SOFTWARE_VELOCITY_LIMIT
  double software_force_impulse_limit_n_per_s = 0.0;  ///< HD_SOFTWARE_FORCE_IMPULSE_LIMIT [N/ms] * 1000
  double force_ramping_rate_n_per_s = 0.0;            ///< HD_FORCE_RAMPING_RATE
  bool has_motor_temperature = false;                 ///< HD_MOTOR_TEMPERATURE answers (a model, not a sensor)
  Vec3<double> usable_workspace_min_m;                ///< HD_USABLE_WORKSPACE_DIMENSIONS, scene frame
  Vec3<double> usable_workspace_max_m;
  Vec3<double> max_workspace_min_m;  ///< HD_MAX_WORKSPACE_DIMENSIONS, scene frame
  Vec3<double> max_workspace_max_m;
  Vec3<double> workspace_centre_mm;  ///< the scene origin in the device frame [mm]
  double tabletop_offset_m = 0.0;    ///< HD_TABLETOP_OFFSET
  int input_dof = 0;
  int output_dof = 0;
  int calibration_styles = 0;  ///< HD_CALIBRATION_STYLE bitmask
  int calibration_style = 0;   ///< the one used: auto > inkwell > encoder reset
};

// ClockedTick, TickVerdict and ClockedTickFn: the seam's (hal/device.hpp); the vendor's
// scheduler is this device's clock (Clocking::kDeviceThread).

enum class OmniPhase : std::uint8_t {
  kIdle,         ///< opened, not started
  kCalibrating,  ///< running, forces off until hdCheckCalibration says OK
  kRunning,      ///< forces on
  kHeld,         ///< a force error: zero force for the hold time
  kRamping,      ///< forces ramping in (after calibration or a force error)
  kStopped,      ///< the run ended (stop(), the tick's kStop, or a fatal error)
};
std::string_view to_string(OmniPhase p) noexcept;

/// Published by the servo thread every tick; read from any thread with OmniDevice::status().
struct OmniStatus {
  std::int64_t tick = 0;                     ///< ClockedTick::tick of the last frame
  std::int64_t frames = 0;                   ///< frames run since start()
  Vec3<double> position_m;                   ///< scene frame
  Vec3<double> force_n;                      ///< commanded this tick after gating and cap, scene frame
  double force_scale = 0.0;                  ///< 0 (off/held) .. 1 (full)
  double update_rate_hz = 0.0;               ///< HD_INSTANTANEOUS_UPDATE_RATE
  double motor_temperature = -1.0;           ///< hottest motor, 0 cold .. 1 warm; -1 unknown
  std::uint32_t calibration = 0;             ///< last hdCheckCalibration answer
  std::uint32_t calibration_errors = 0;      ///< HD errors from checking or updating calibration
  std::uint32_t last_calibration_error = 0;  ///< the most recent of them (0 none)
  std::uint32_t last_hd_error = 0;           ///< most recent HD error code (0 none)
  std::int32_t last_hd_internal_error = 0;
  std::uint32_t hd_errors = 0;     ///< HD errors seen since start()
  std::uint32_t force_errors = 0;  ///< of which force errors
  std::uint32_t overruns = 0;      ///< ticks that overran their period
  std::uint32_t buttons = 0;       ///< HD_CURRENT_BUTTONS
  OmniPhase phase = OmniPhase::kIdle;
  DeviceStatus device_status = DeviceStatus::kNotReady;  ///< what read() said this tick
};

/// What start() reports.
struct OmniStarted {
  double period_s = 0.0;  ///< nominal tick period (ControllerConfig::period_s)
};

class OmniDevice final : public DeviceDriver {
 public:
  ~OmniDevice() override;

  // ---- DeviceDriver: read() and write() only inside the tick (the servo thread) ----
  /// This frame's reading. kOk; kNotReady while uncalibrated or held after a force error (the
  /// position is filled but must not drive effects); kDisconnected / kDeviceFault /
  /// kProtocolError on the tick a fatal HD error stops the loop (see hd_errors.hpp); kNotReady
  /// outside a frame.
  DeviceStatus read(DeviceReading& reading) noexcept override;
  /// The force for this frame [N, scene frame]; the device gates, ramps and caps it before
  /// hdSetDoublev(HD_CURRENT_FORCE) at the end of the frame. A non-finite force commands zero.
  DeviceStatus write(const Vec3<double>& force_n) noexcept override;
  /// Any thread, never blocks: forces are zeroed and output disabled at the next frame, and
  /// stay off until the device is closed. The HD API is only called from the servo thread
  /// (its thread safety is not documented), so if that thread itself hangs this cannot help.
  void emergency_zero() noexcept override;
  const DeviceInfo& info() const noexcept override { return info_; }
  std::string last_error() const override;
  /// The device-clocked run through the seam: start(), wait until the tick's kStop or a fatal
  /// error ends it, stop(); `device_stopped` names the error when the device ended it.
  Result<ClockedEnd> run_clocked(ClockedTickFn tick, void* context) override;

  // ---- Device-clocked run (owner thread) ----
  /// Registers our frame with hdScheduleAsynchronous and starts the vendor scheduler unless
  /// another open device already did (one scheduler per process); `tick` then runs once per
  /// period in the servo thread, which every device's frame shares. Fails when already running
  /// or when the scheduler reports an error.
  Result<OmniStarted> start(ClockedTickFn tick, void* context);
  /// Asks the loop to end at its next frame (any thread, never blocks).
  void request_stop() noexcept;
  /// Ends the run: the next frame zeroes and disables forces and unschedules itself; waits for
  /// it (at most `timeout`, then unschedules anyway) and, if no other device still runs, stops
  /// the scheduler. Idempotent.
  void stop(std::chrono::milliseconds timeout = std::chrono::milliseconds(200));
  /// True from start() until the frame has unscheduled itself.
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }
  /// Waits until the loop ends by itself (a fatal error, the tick's kStop) or `timeout`.
  bool wait_until_stopped(std::chrono::milliseconds timeout) const;

  // ---- Any thread ----
  OmniStatus status() const noexcept { return status_.load(); }
  /// How many frames have published a status (for waiting on the loop in tools and tests).
  std::uint64_t status_version() const noexcept { return status_.version(); }
  const OmniLimits& limits() const noexcept { return limits_; }
  /// Whether closing calls hdDisableDevice (OmniOptions::disable_device_on_close).
  bool disables_device_on_close() const noexcept { return disable_on_close_; }
  const hd::Library& library() const noexcept { return *library_; }

 private:
  friend Result<std::unique_ptr<OmniDevice>> open_omni(const OmniOptions& options);
  OmniDevice(const hd::Library& library, hd::HHD handle, const OmniOptions& options);

  static hd::HDCallbackCode frame_callback(void* self) noexcept;
  hd::HDCallbackCode frame() noexcept;
  void drain_errors() noexcept;
  void note_error(const hd::HDErrorInfo& e) noexcept;
  void hold_force(std::int64_t ticks) noexcept;
  void check_calibration() noexcept;
  bool drain_calibration_errors() noexcept;
  void read_temperature() noexcept;
  double force_scale() const noexcept;
  hd::HDCallbackCode end_run() noexcept;

  const hd::Library* library_;
  const hd::HdFunctions* hd_;
  hd::HHD handle_;
  OmniOptions options_;
  OmniLimits limits_;
  bool disable_on_close_ = true;
  DeviceInfo info_;
  omni::Frame frame_;
  double period_s_ = 0.0;
  std::int64_t calibration_check_ticks_ = 1;
  std::int64_t temperature_ticks_ = 1;
  std::int64_t next_calibration_check_ = 0;
  std::int64_t next_temperature_read_ = 0;

  // Servo-thread state (touched only by the scheduler's thread while running).
  ClockedTickFn tick_fn_ = nullptr;
  void* tick_context_ = nullptr;
  bool in_frame_ = false;
  DeviceReading reading_{};
  DeviceStatus reading_status_ = DeviceStatus::kNotReady;
  Vec3<double> requested_n_{};
  std::int64_t tick_ = 0;
  std::int64_t frames_ = 0;
  bool calibrated_ = false;
  bool forces_enabled_ = false;
  bool shutting_down_ = false;  // the next frame is the last
  std::int64_t hold_until_tick_ = 0;
  std::int64_t ramp_start_tick_ = 0;
  std::int64_t ramp_ticks_ = 1;
  bool held_ = false;  // a force error holds force at zero until hold_until_tick_
  bool warm_hold_ = false;
  bool temperature_readable_ = false;
  int consecutive_overruns_ = 0;
  hd::HDerror fatal_code_ = hd::kSuccess;
  DeviceStatus fatal_status_ = DeviceStatus::kOk;
  OmniStatus published_{};

  // Cross-thread (lock-free).
  omni::SeqLock<OmniStatus> status_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> emergency_{false};
  std::atomic<bool> callback_done_{true};
  hd::HDSchedulerHandle schedule_handle_ = 0;
  bool holds_scheduler_ = false;  // counted among the devices running the one scheduler
  // Why the run ended or degraded last, for last_error() (written by the servo thread).
  std::atomic<std::uint32_t> last_code_{0};
  std::atomic<std::int32_t> last_internal_{0};
  std::atomic<std::int64_t> last_code_tick_{0};
  std::atomic<std::uint8_t> end_reason_{0};               // EndReason in omni_device.cpp
  std::atomic<std::uint32_t> overrun_run_{0};             // overruns in a row when the run ended
  std::atomic<std::uint32_t> last_calibration_error_{0};  // for last_error() while calibrating
};

/// Whether this is OpenHaptics' FireWire stack (AE 3.0 for the FireWire Phantom Omni): an HD
/// version 3.0 to 3.3 ("3.00.66"), or, when the version is unknown, a model type naming the
/// Omni. OpenHaptics 3.4 dropped FireWire (OMNI.md §1.1).
bool is_firewire_stack(std::string_view hd_version, std::string_view model);

/// Loads OpenHaptics, opens the device, reads its limits and calibrates what can be calibrated
/// without the scheduler. Every failure says what to install or fix. Several devices may be
/// open in one process, each by its own OmniOptions::device_name (the same name twice is
/// refused); OpenHaptics has one scheduler, at one rate, for all of them, so every device is
/// opened before any starts (opening while one runs is refused) and all share the rate. Each
/// started device schedules its own frame; the first start() starts the scheduler, the last
/// stop() stops it.
Result<std::unique_ptr<OmniDevice>> open_omni(const OmniOptions& options = {});

}  // namespace toonforce
