// SPDX-License-Identifier: Apache-2.0
// The Omni/Touch device over OpenHaptics HD: start-up (open_omni), the frame the vendor
// scheduler calls every tick, and the messages. See omni_device.hpp for the contract.
#include "toonforce/hal/omni/omni_device.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <mutex>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "toonforce/hal/omni/hd_errors.hpp"
#include "toonforce/hal/omni/hd_library.hpp"

namespace toonforce {
namespace {

// OpenHaptics runs ONE scheduler per process for every device (HDAPI: each device is
// initialised by name with hdInitDevice before hdStartScheduler, which is called once;
// hdStopScheduler stops it for all; every scheduled callback runs each tick on its one thread).
// This is its owner: the names of the open devices, and how many hold a share of the running
// scheduler; the first start() starts it, the last stop() stops it.
struct SchedulerOwner {
  std::mutex mu;
  std::vector<std::string> open;  // OmniOptions::device_name of each open device ("": the default)
  double rate_hz = 0.0;           // the one scheduler's rate, set by the first device opened
  int running = 0;                // devices holding a share of the running scheduler
};

SchedulerOwner& scheduler_owner() {
  static auto* owner = new SchedulerOwner();  // never destroyed: devices may outlive statics
  return *owner;
}

std::string shown_device_name(const std::string& name) {
  return name.empty() ? std::string("HD_DEFAULT_DEVICE") : fmt::format("\"{}\"", name);
}

enum class EndReason : std::uint8_t { kNone, kStopRequested, kTickStopped, kFatalHdError, kOverruns };

constexpr int kMaxErrorsPerDrain = 16;  // bounded work per frame

// ---- start-up helpers (owner thread, may allocate) -----------------------------------------

/// Pops every pending error; returns the most recent one (kSuccess when there was none).
hd::HDErrorInfo take_error(const hd::HdFunctions& f) {
  hd::HDErrorInfo first{hd::kSuccess, 0, 0};
  for (int i = 0; i < kMaxErrorsPerDrain; ++i) {
    const hd::HDErrorInfo e = f.hdGetError();
    if (e.errorCode == hd::kSuccess) break;
    if (first.errorCode == hd::kSuccess) first = e;
  }
  return first;
}

/// "HD_COMM_ERROR (0x302, internal -28: <the library's own description>)".
std::string describe(const hd::HdFunctions& f, const hd::HDErrorInfo& e) {
  const char* vendor = f.hdGetErrorString(e.errorCode);
  return fmt::format("{} (0x{:03x}, internal {}{}{})", hd::error_name(e.errorCode), e.errorCode, e.internalErrorCode,
                     vendor != nullptr && vendor[0] != '\0' ? ": " : "", vendor != nullptr ? vendor : "");
}

std::string get_string(const hd::HdFunctions& f, hd::HDenum name) {
  const char* s = f.hdGetString(name);
  const bool failed = take_error(f).errorCode != hd::kSuccess;
  return failed || s == nullptr ? std::string{} : std::string(s);
}

/// Reads `n` doubles; false (and the values untouched beyond what the call wrote) on an error.
bool get_doubles(const hd::HdFunctions& f, hd::HDenum name, double* values) {
  f.hdGetDoublev(name, values);
  return take_error(f).errorCode == hd::kSuccess;
}

bool get_int(const hd::HdFunctions& f, hd::HDenum name, int& value) {
  f.hdGetIntegerv(name, &value);
  return take_error(f).errorCode == hd::kSuccess;
}

bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

std::int64_t ticks_for(double seconds, double period_s) {
  return std::max<std::int64_t>(1, std::llround(seconds / period_s));
}

std::string check_options(const OmniOptions& o) {
  const auto bad_time = [](double s) { return !std::isfinite(s) || s < 0.0; };
  if (!std::isfinite(o.scheduler_rate_hz) || o.scheduler_rate_hz < 100.0 || o.scheduler_rate_hz > 10000.0) {
    return fmt::format("scheduler rate {} Hz is out of range: OpenHaptics runs at 500, 1000, 1600 "
                       "or 2000 Hz (use 1000 unless you know better)",
                       o.scheduler_rate_hz);
  }
  if (!std::isfinite(o.max_force_n) || o.max_force_n < 0.0) {
    return fmt::format("max force {} N must be >= 0 (0: the device's nominal continuous force)", o.max_force_n);
  }
  if (bad_time(o.enable_ramp_s) || bad_time(o.force_error_hold_s) || bad_time(o.recovery_ramp_s) ||
      bad_time(o.warm_motors_hold_s) || bad_time(o.calibration_check_period_s) || bad_time(o.temperature_period_s)) {
    return "ramp, hold and check times must be finite and >= 0 s";
  }
  if (!(o.warm_motors_resume_temperature > 0.0 && o.warm_motors_resume_temperature <= 1.0)) {
    return "warm_motors_resume_temperature must be in (0, 1]";
  }
  if (o.max_consecutive_overruns < 1) return "max_consecutive_overruns must be >= 1";
  if (o.workspace_centre_mm && !(std::isfinite(o.workspace_centre_mm->x) && std::isfinite(o.workspace_centre_mm->y) &&
                                 std::isfinite(o.workspace_centre_mm->z))) {
    return "the workspace centre must be finite";
  }
  return {};
}

/// Takes `name` off the open devices (the owner's lock held).
void release_name(SchedulerOwner& owner, const std::string& name) {
  const auto it = std::find(owner.open.begin(), owner.open.end(), name);
  if (it != owner.open.end()) owner.open.erase(it);
}

/// Releases a device name claimed by open_omni unless disarmed (runs with the owner's lock held).
struct OpenClaim {
  SchedulerOwner& owner;
  std::string name;
  bool armed = true;
  ~OpenClaim() {
    if (armed) release_name(owner, name);
  }
};

}  // namespace

bool is_firewire_stack(std::string_view hd_version, std::string_view model) {
  // OpenHaptics 3.4 dropped FireWire; the FireWire Omni runs on AE 3.0 (OMNI.md §1.1), whose
  // HD_VERSION reads like "3.00.66". Any 3.0-3.3 library, or a model named Omni when the
  // version is unknown, is taken for the FireWire stack.
  if (hd::major_version(hd_version) == 3) {
    const auto dot = hd_version.find('.');
    if (dot != std::string_view::npos) {
      const int minor = hd::major_version(hd_version.substr(dot + 1));
      if (minor >= 0) return minor < 4;
    }
  }
  if (!hd_version.empty()) return false;
  std::string lower(model);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return lower.find("omni") != std::string::npos;
}

std::string_view to_string(OmniPhase p) noexcept {
  switch (p) {
    case OmniPhase::kIdle: return "idle";
    case OmniPhase::kCalibrating: return "calibrating";
    case OmniPhase::kRunning: return "running";
    case OmniPhase::kHeld: return "held";
    case OmniPhase::kRamping: return "ramping";
    case OmniPhase::kStopped: return "stopped";
  }
  return "?";
}

// ---- open ------------------------------------------------------------------------------------

Result<std::unique_ptr<OmniDevice>> open_omni(const OmniOptions& options) {
  if (std::string problem = check_options(options); !problem.empty()) {
    return Error{"Omni options: " + problem};
  }
  // Opening is serialised with every other open, start and stop of an Omni in the process.
  SchedulerOwner& owner = scheduler_owner();
  std::lock_guard owner_lock(owner.mu);
  const std::string shown_name = shown_device_name(options.device_name);
  if (std::find(owner.open.begin(), owner.open.end(), options.device_name) != owner.open.end()) {
    return Error{fmt::format("the Omni/Touch {} is already open in this process: each device opens once (several "
                             "devices: give each its own device name, as Touch_Setup configured it)",
                             shown_name)};
  }
  if (owner.running > 0) {
    return Error{fmt::format("cannot open the Omni/Touch {}: OpenHaptics' scheduler is already running for {} "
                             "device(s), and every device is initialised before its one scheduler starts: open "
                             "every Omni first, then start them",
                             shown_name, owner.running)};
  }
  if (!owner.open.empty() && owner.rate_hz != options.scheduler_rate_hz) {
    return Error{fmt::format("cannot open the Omni/Touch {} at {} Hz: the devices already open run at {} Hz, and "
                             "OpenHaptics has one scheduler, at one rate, for all of them",
                             shown_name, options.scheduler_rate_hz, owner.rate_hz)};
  }
  owner.open.push_back(options.device_name);
  OpenClaim claim{owner, options.device_name};

  const hd::LoadOutcome loaded = hd::load_library(options.library_path);
  if (loaded.library == nullptr) return Error{loaded.message};
  const hd::Library& library = *loaded.library;
  const hd::HdFunctions& f = library.functions();
  static_cast<void>(take_error(f));  // nothing left over from an earlier use

  const char* name = options.device_name.empty() ? nullptr : options.device_name.c_str();
  const hd::HHD handle = f.hdInitDevice(name);
  if (const hd::HDErrorInfo e = take_error(f); e.errorCode != hd::kSuccess || handle == hd::kInvalidHandle) {
    return Error{fmt::format(
        "OpenHaptics could not open the device {} ({}): {}. Check that it is plugged in and set up "
        "with the vendor's Touch_Setup (Touch) or PHANTOM Configuration (FireWire Omni); that this "
        "user may open its port (`toonforce devices` tells); try the device name configured there "
        "(\"Default Device\") instead of the default; and outside the US set "
        "LC_NUMERIC=en_US.UTF-8, which the driver needs to read its configuration.",
        shown_name, library.path(), e.errorCode != hd::kSuccess ? describe(f, e) : std::string("no device handle"))};
  }
  // Version and model first: they decide whether closing may call hdDisableDevice.
  // Version: the library says which HD API it implements (the file name may not).
  const std::string version = get_string(f, hd::kVersion);
  const std::string model = get_string(f, hd::kDeviceModelType);
  const bool disable_on_close = options.disable_device_on_close.value_or(!is_firewire_stack(version, model));

  // From here on, a failure must release the device (hdDisableDevice, unless it must not be
  // called on this model).
  struct InitGuard {
    const hd::HdFunctions& f;
    hd::HHD handle;
    bool disable;
    bool armed = true;
    ~InitGuard() {
      if (armed && disable) {
        f.hdDisableDevice(handle);
        static_cast<void>(take_error(f));
      }
    }
  } init_guard{f, handle, disable_on_close};
  if (const int major = hd::major_version(version); major >= 0 && major != hd::kSupportedMajorVersion) {
    return Error{fmt::format("{} reports OpenHaptics HD version {}, but toonforce needs version {} (3.4 for the Touch, "
                             "3.0 for the FireWire Omni). Install OpenHaptics 3.4 from 3D Systems, or set {} to its "
                             "libHD.so.",
                             library.path(), version, hd::kSupportedMajorVersion, hd::kLibraryEnvVar)};
  }

  // Limits, read once (OMNI.md §2.2 item 8); never hard-coded (§3).
  OmniLimits limits;
  double value = 0.0;
  if (!get_doubles(f, hd::kNominalMaxForce, &value) || !finite_positive(value)) {
    return Error{fmt::format("{} did not report a usable HD_NOMINAL_MAX_FORCE ({}): toonforce will "
                             "not command forces without the device's own limit",
                             library.path(), value)};
  }
  limits.max_force_n = value;
  const auto optional_double = [&](hd::HDenum what, double scale) {
    double v = 0.0;
    return get_doubles(f, what, &v) && std::isfinite(v) && v > 0.0 ? v * scale : 0.0;
  };
  limits.max_continuous_force_n = optional_double(hd::kNominalMaxContinuousForce, 1.0);
  // The cap: the continuous force by default, as public drivers cap well below the peak
  // (sawSensablePhantom at 2 N, OMNI.md §3); the peak is for short bursts, and only on request.
  if (options.max_force_n > 0.0) {
    limits.force_cap_n = std::min(options.max_force_n, limits.max_force_n);
    limits.force_cap_source = options.max_force_n > limits.max_force_n
                                  ? "the device's peak HD_NOMINAL_MAX_FORCE (the option asked for more)"
                                  : "the option";
  } else if (limits.max_continuous_force_n > 0.0) {
    limits.force_cap_n = std::min(limits.max_continuous_force_n, limits.max_force_n);
    limits.force_cap_source = "the device's HD_NOMINAL_MAX_CONTINUOUS_FORCE (the default)";
  } else {
    limits.force_cap_n = limits.max_force_n;
    limits.force_cap_source = "the device's peak HD_NOMINAL_MAX_FORCE (it reports no continuous force)";
  }
  limits.max_stiffness_n_per_m = optional_double(hd::kNominalMaxStiffness, 1000.0);  // N/mm
  limits.max_damping_n_s_per_m = optional_double(hd::kNominalMaxDamping, 1000.0);    // N s/mm
  limits.software_velocity_limit_m_per_s = optional_double(hd::kSoftwareVelocityLimit, 1e-3);
  limits.software_force_impulse_limit_n_per_s = optional_double(hd::kSoftwareForceImpulseLimit, 1000.0);
  limits.force_ramping_rate_n_per_s = optional_double(hd::kForceRampingRate, 1.0);
  limits.tabletop_offset_m = [&] {
    double v = 0.0;
    return get_doubles(f, hd::kTabletopOffset, &v) && std::isfinite(v) ? v * 1e-3 : 0.0;
  }();
  {
    double temperatures[6] = {-1.0, -1.0, -1.0, -1.0, -1.0, -1.0};
    limits.has_motor_temperature = get_doubles(f, hd::kMotorTemperature, temperatures);
  }
  static_cast<void>(get_int(f, hd::kInputDof, limits.input_dof));
  static_cast<void>(get_int(f, hd::kOutputDof, limits.output_dof));

  omni::DeviceBoxMm usable{};
  omni::DeviceBoxMm maximal{};
  const bool has_usable = get_doubles(f, hd::kUsableWorkspaceDimensions, usable.data());
  const bool has_max = get_doubles(f, hd::kMaxWorkspaceDimensions, maximal.data());
  const auto box_ok = [](const omni::DeviceBoxMm& b) {
    return std::all_of(b.begin(), b.end(), [](double v) { return std::isfinite(v); }) && b[0] < b[3] && b[1] < b[4] &&
           b[2] < b[5];
  };
  Vec3<double> centre{};
  if (options.workspace_centre_mm) {
    centre = *options.workspace_centre_mm;
  } else if (has_usable && box_ok(usable)) {
    centre = omni::Frame::centre_of(usable);
  } else if (has_max && box_ok(maximal)) {
    centre = omni::Frame::centre_of(maximal);
  } else {
    return Error{fmt::format("{} reported no workspace (HD_USABLE_WORKSPACE_DIMENSIONS), so the "
                             "scene origin is unknown: give the workspace centre explicitly",
                             library.path())};
  }
  const omni::Frame frame{centre};
  limits.workspace_centre_mm = centre;
  if (has_usable && box_ok(usable)) {
    const auto box = frame.scene_box_m(usable);
    limits.usable_workspace_min_m = box[0];
    limits.usable_workspace_max_m = box[1];
  }
  if (has_max && box_ok(maximal)) {
    const auto box = frame.scene_box_m(maximal);
    limits.max_workspace_min_m = box[0];
    limits.max_workspace_max_m = box[1];
  }

  // Calibration: prefer auto, then inkwell, then encoder reset (OpenHaptics' calibration
  // example). Encoder reset happens now, with the arm in its reset pose; the others are
  // checked and updated inside the loop, and forces stay off until the check says OK.
  static_cast<void>(get_int(f, hd::kCalibrationStyle, limits.calibration_styles));
  const int styles = limits.calibration_styles;
  limits.calibration_style = (styles & hd::kCalibrationAuto) != 0           ? hd::kCalibrationAuto
                             : (styles & hd::kCalibrationInkwell) != 0      ? hd::kCalibrationInkwell
                             : (styles & hd::kCalibrationEncoderReset) != 0 ? hd::kCalibrationEncoderReset
                                                                            : 0;
  if (limits.calibration_style == hd::kCalibrationEncoderReset && options.encoder_reset_at_open) {
    const hd::HDenum state = f.hdCheckCalibration();
    static_cast<void>(take_error(f));
    if (state != hd::kCalibrationOk) {
      f.hdUpdateCalibration(static_cast<hd::HDenum>(hd::kCalibrationEncoderReset));
      if (const hd::HDErrorInfo e = take_error(f); e.errorCode != hd::kSuccess) {
        return Error{fmt::format("encoder-reset calibration failed: {}. Put the arm in its reset "
                                 "pose and open it again.",
                                 describe(f, e))};
      }
    }
  }

  f.hdSetSchedulerRate(static_cast<hd::HDulong>(std::lround(options.scheduler_rate_hz)));
  if (const hd::HDErrorInfo e = take_error(f); e.errorCode != hd::kSuccess) {
    return Error{fmt::format("the OpenHaptics scheduler refused {} Hz: {}. The reference guide lists "
                             "500, 1000 and 1600 Hz (FireWire) and 2000 Hz (PCI/EPP).",
                             options.scheduler_rate_hz, describe(f, e))};
  }

  auto device = std::unique_ptr<OmniDevice>(new OmniDevice(library, handle, options));
  device->limits_ = limits;
  device->frame_ = frame;
  device->temperature_readable_ = limits.has_motor_temperature;
  const std::string serial = get_string(f, hd::kDeviceSerialNumber);
  device->disable_on_close_ = disable_on_close;
  device->info_.name = fmt::format("{}{} via OpenHaptics {} ({})", model.empty() ? "OpenHaptics device" : model,
                                   serial.empty() ? "" : fmt::format(" (serial {})", serial),
                                   version.empty() ? "?" : version, library.path());
  device->info_.max_force_n = limits.force_cap_n;
  device->info_.max_continuous_force_n = limits.max_continuous_force_n;
  device->info_.workspace_min_m = limits.usable_workspace_min_m;
  device->info_.workspace_max_m = limits.usable_workspace_max_m;
  device->info_.nominal_rate_hz = options.scheduler_rate_hz;
  device->info_.clocking = Clocking::kDeviceThread;  // the vendor's scheduler calls the tick
  init_guard.armed = false;
  claim.armed = false;  // the device releases it
  owner.rate_hz = options.scheduler_rate_hz;
  return device;
}

OmniDevice::OmniDevice(const hd::Library& library, hd::HHD handle, const OmniOptions& options)
    : library_(&library),
      hd_(&library.functions()),
      handle_(handle),
      options_(options),
      period_s_(1.0 / options.scheduler_rate_hz) {
  calibration_check_ticks_ = ticks_for(options.calibration_check_period_s, period_s_);
  temperature_ticks_ = ticks_for(options.temperature_period_s, period_s_);
}

OmniDevice::~OmniDevice() {
  stop();
  // sawSensablePhantom never calls hdDisableDevice: "this seems to crash with FireWire based
  // models" (mtsSensableHD.cpp, Kill). The scheduler is stopped and forces are off by now.
  if (disable_on_close_) {
    hd_->hdDisableDevice(handle_);
    static_cast<void>(take_error(*hd_));
  }
  {
    SchedulerOwner& owner = scheduler_owner();
    std::lock_guard lock(owner.mu);
    release_name(owner, options_.device_name);
  }
  // The library stays loaded (never unloaded, hd_library.hpp).
}

// ---- run control (owner thread) -------------------------------------------------------------

Result<ClockedEnd> OmniDevice::run_clocked(ClockedTickFn tick, void* context) {
  auto started = start(tick, context);
  if (!started) return Error{started.error()};
  while (running()) static_cast<void>(wait_until_stopped(std::chrono::milliseconds(100)));
  stop();
  ClockedEnd end;
  // A fatal HD error or too many overruns is the device's doing; a kStop or stop() is ours.
  const auto reason = static_cast<EndReason>(end_reason_.load());
  if (reason == EndReason::kFatalHdError || reason == EndReason::kOverruns) end.device_stopped = last_error();
  return end;
}

Result<OmniStarted> OmniDevice::start(ClockedTickFn tick, void* context) {
  if (tick == nullptr) return Error{"start(): no tick function"};
  if (running_.load()) return Error{"start(): the Omni is already running"};
  if (emergency_.load()) return Error{"start(): emergency zero was requested; close and reopen the device"};
  const hd::HdFunctions& f = *hd_;

  tick_fn_ = tick;
  tick_context_ = context;
  in_frame_ = false;
  reading_ = {};
  reading_status_ = DeviceStatus::kNotReady;
  tick_ = 0;
  frames_ = 0;
  calibrated_ = false;
  forces_enabled_ = false;
  shutting_down_ = false;
  hold_until_tick_ = 0;
  ramp_start_tick_ = 0;
  ramp_ticks_ = 1;
  held_ = false;
  warm_hold_ = false;
  consecutive_overruns_ = 0;
  next_calibration_check_ = 0;
  next_temperature_read_ = 0;
  fatal_code_ = hd::kSuccess;
  fatal_status_ = DeviceStatus::kOk;
  published_ = {};
  published_.phase = OmniPhase::kCalibrating;
  published_.motor_temperature = -1.0;
  status_.store(published_);
  stop_requested_.store(false);
  end_reason_.store(static_cast<std::uint8_t>(EndReason::kNone));
  last_code_.store(0);
  last_internal_.store(0);
  last_code_tick_.store(0);
  overrun_run_.store(0);
  last_calibration_error_.store(0);
  callback_done_.store(false);
  running_.store(true, std::memory_order_release);

  // The one scheduler: this device's callback joins it; the first device to start starts it.
  SchedulerOwner& owner = scheduler_owner();
  std::lock_guard owner_lock(owner.mu);
  // Errors left over, only while no other device runs: the error stack is the library's, and a
  // running device's frames drain their own.
  if (owner.running == 0) static_cast<void>(take_error(f));
  schedule_handle_ = f.hdScheduleAsynchronous(&OmniDevice::frame_callback, this, hd::kMaxSchedulerPriority);
  if (const hd::HDErrorInfo e = take_error(f); e.errorCode != hd::kSuccess) {
    running_.store(false);
    callback_done_.store(true);
    return Error{fmt::format("OpenHaptics refused the servo callback: {}", describe(f, e))};
  }
  if (owner.running == 0) {
    f.hdStartScheduler();
    if (const hd::HDErrorInfo e = take_error(f); e.errorCode != hd::kSuccess) {
      // No frame has run (or will): take the callback off and stop whatever did start.
      f.hdUnschedule(schedule_handle_);
      running_.store(false, std::memory_order_release);
      callback_done_.store(true);
      f.hdStopScheduler();
      static_cast<void>(take_error(f));
      return Error{fmt::format("the OpenHaptics scheduler did not start: {}. {}", describe(f, e),
                               e.errorCode == hd::kTimerError
                                   ? "The servo timer could not keep its rate: try a lower rate, or "
                                     "run as root or with CAP_SYS_NICE."
                                   : "")};
    }
  }
  ++owner.running;
  holds_scheduler_ = true;
  return OmniStarted{period_s_};
}

void OmniDevice::request_stop() noexcept { stop_requested_.store(true, std::memory_order_release); }

void OmniDevice::stop(std::chrono::milliseconds timeout) {
  const hd::HdFunctions& f = *hd_;
  if (running_.load(std::memory_order_acquire)) {
    request_stop();
    if (!wait_until_stopped(timeout)) {
      // The frame did not run in time (a stalled scheduler): take it off anyway.
      f.hdUnschedule(schedule_handle_);
      running_.store(false, std::memory_order_release);
    }
    if (end_reason_.load() == static_cast<std::uint8_t>(EndReason::kNone)) {
      end_reason_.store(static_cast<std::uint8_t>(EndReason::kStopRequested));
    }
  }
  if (holds_scheduler_) {
    holds_scheduler_ = false;
    SchedulerOwner& owner = scheduler_owner();
    std::lock_guard owner_lock(owner.mu);
    if (--owner.running == 0) {
      // The last running device stops the one scheduler. No servo thread any more: forces off
      // from here is safe, whatever the last frame did. While other devices run, this device's
      // last frame turned its forces off (the frame calls the HD API only on the servo thread).
      f.hdStopScheduler();
      f.hdMakeCurrentDevice(handle_);
      f.hdDisable(hd::kForceOutput);
      static_cast<void>(take_error(f));
    }
    OmniStatus last = status_.load();
    last.phase = OmniPhase::kStopped;
    last.force_n = {};
    last.force_scale = 0.0;
    status_.store(last);
  }
}

bool OmniDevice::wait_until_stopped(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (running_.load(std::memory_order_acquire)) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return true;
}

void OmniDevice::emergency_zero() noexcept { emergency_.store(true, std::memory_order_release); }

// ---- the frame (servo thread) ---------------------------------------------------------------

hd::HDCallbackCode OmniDevice::frame_callback(void* self) noexcept { return static_cast<OmniDevice*>(self)->frame(); }

void OmniDevice::note_error(const hd::HDErrorInfo& e) noexcept {
  const hd::ErrorClass c = hd::classify(e.errorCode);
  ++published_.hd_errors;
  published_.last_hd_error = e.errorCode;
  published_.last_hd_internal_error = e.internalErrorCode;
  last_code_.store(e.errorCode, std::memory_order_relaxed);
  last_internal_.store(e.internalErrorCode, std::memory_order_relaxed);
  last_code_tick_.store(tick_, std::memory_order_relaxed);
  if (c == hd::ErrorClass::kForce) {
    ++published_.force_errors;
    if (e.errorCode == hd::kWarmMotors) {
      warm_hold_ = true;
      hold_force(ticks_for(options_.warm_motors_hold_s, period_s_));
    } else {
      hold_force(ticks_for(options_.force_error_hold_s, period_s_));
    }
    return;
  }
  if (fatal_code_ == hd::kSuccess && fatal_status_ == DeviceStatus::kOk) {
    fatal_code_ = e.errorCode;
    fatal_status_ = hd::device_status(c);
    shutting_down_ = true;
    end_reason_.store(static_cast<std::uint8_t>(EndReason::kFatalHdError), std::memory_order_relaxed);
  }
}

void OmniDevice::drain_errors() noexcept {
  for (int i = 0; i < kMaxErrorsPerDrain; ++i) {
    const hd::HDErrorInfo e = hd_->hdGetError();
    if (e.errorCode == hd::kSuccess) return;
    note_error(e);
  }
}

void OmniDevice::hold_force(std::int64_t ticks) noexcept {
  held_ = true;
  // `ticks` whole frames of zero force after this one (whose force may have gone out already).
  hold_until_tick_ = std::max(hold_until_tick_, tick_ + 1 + ticks);
}

void OmniDevice::check_calibration() noexcept {
  // Outside the frame, before hdBeginFrame, and an update only on NEEDS_UPDATE: what
  // OpenHaptics' calibration example (its UpdateCalibrationCallback) and the ROS Omni node's
  // servo callback do. On NEEDS_MANUAL_INPUT an update has nothing to work from (the real
  // library answers it with an error): the person must act first (dock the stylus, sweep the
  // arm), which last_error() says. An error from the check or the update means "still
  // calibrating" (sawSensablePhantom reports it as "calibration failed" and carries on), never
  // the end of the run: forces stay off and the next check tries again. Errors from elsewhere
  // were drained before this call, so the ones popped here are calibration's own.
  const hd::HdFunctions& f = *hd_;
  hd::HDenum state = f.hdCheckCalibration();
  bool failed = drain_calibration_errors();
  const int style = limits_.calibration_style;
  // An encoder reset only makes sense in the reset pose, so it happens at open, not here.
  if (!failed && state == hd::kCalibrationNeedsUpdate &&
      (style == hd::kCalibrationAuto || style == hd::kCalibrationInkwell)) {
    f.hdUpdateCalibration(static_cast<hd::HDenum>(style));
    failed = drain_calibration_errors();
    if (!failed) {
      state = f.hdCheckCalibration();
      failed = drain_calibration_errors();
    }
  }
  published_.calibration = state;
  if (failed || state != hd::kCalibrationOk) {
    calibrated_ = false;
    return;
  }
  if (!calibrated_) {
    calibrated_ = true;
    ramp_start_tick_ = tick_;
    ramp_ticks_ = ticks_for(options_.enable_ramp_s, period_s_);
  }
}

bool OmniDevice::drain_calibration_errors() noexcept {
  bool any = false;
  for (int i = 0; i < kMaxErrorsPerDrain; ++i) {
    const hd::HDErrorInfo e = hd_->hdGetError();
    if (e.errorCode == hd::kSuccess) break;
    any = true;
    ++published_.calibration_errors;
    published_.last_calibration_error = e.errorCode;
    last_calibration_error_.store(e.errorCode, std::memory_order_relaxed);
  }
  return any;
}

void OmniDevice::read_temperature() noexcept {
  const hd::HdFunctions& f = *hd_;
  double t[6] = {-1.0, -1.0, -1.0, -1.0, -1.0, -1.0};  // 3 or 6 motors answer
  f.hdGetDoublev(hd::kMotorTemperature, t);
  bool unsupported = false;
  for (int i = 0; i < kMaxErrorsPerDrain; ++i) {
    const hd::HDErrorInfo e = f.hdGetError();
    if (e.errorCode == hd::kSuccess) break;
    // An optional query this device does not answer is not a fault: stop asking.
    if (hd::classify(e.errorCode) == hd::ErrorClass::kFunction) {
      unsupported = true;
    } else {
      note_error(e);
    }
  }
  if (unsupported) {
    temperature_readable_ = false;
    published_.motor_temperature = -1.0;
    return;
  }
  double hottest = -1.0;
  for (const double v : t) {
    if (std::isfinite(v) && v >= 0.0) hottest = std::max(hottest, v);
  }
  published_.motor_temperature = hottest;
}

double OmniDevice::force_scale() const noexcept {
  if (!calibrated_ || held_ || !forces_enabled_) return 0.0;
  const double s = static_cast<double>(tick_ - ramp_start_tick_) / static_cast<double>(ramp_ticks_);
  return std::clamp(s, 0.0, 1.0);
}

hd::HDCallbackCode OmniDevice::frame() noexcept {
  const hd::HdFunctions& f = *hd_;
  f.hdMakeCurrentDevice(handle_);
  drain_errors();  // anything raised between frames is the loop's business, not calibration's
  // Calibration before the frame (see check_calibration). Periodic checks go by tick numbers,
  // so skipped periods do not skip a check; tick_ is the previous frame's here.
  if (tick_ >= next_calibration_check_) {
    check_calibration();
    next_calibration_check_ = tick_ + calibration_check_ticks_;
  }
  f.hdBeginFrame(handle_);
  in_frame_ = true;
  const bool stop_requested = stop_requested_.load(std::memory_order_acquire);
  drain_errors();

  // The clock: the instantaneous rate says how long this tick really was, skipped periods
  // included (OMNI.md §2.2 item 7; there is no overrun error code, §2.3).
  double rate_hz = 0.0;
  f.hdGetDoublev(hd::kInstantaneousUpdateRate, &rate_hz);
  double dt_s = period_s_;
  bool overran = false;
  if (frames_ > 0) {
    if (std::isfinite(rate_hz) && rate_hz > 0.0) dt_s = 1.0 / rate_hz;
    const std::int64_t periods = std::max<std::int64_t>(1, std::llround(dt_s / period_s_));
    tick_ += periods;
    overran = periods > 1;
  } else {
    // hdStartScheduler enables forces (OMNI.md §2.2 item 5): off until calibration is OK.
    f.hdDisable(hd::kForceOutput);
    forces_enabled_ = false;
  }

  // This frame's state, in the scene frame.
  double position[3] = {0.0, 0.0, 0.0};
  double velocity[3] = {0.0, 0.0, 0.0};
  int buttons = 0;
  f.hdGetDoublev(hd::kCurrentPosition, position);
  if (options_.use_device_velocity) f.hdGetDoublev(hd::kCurrentVelocity, velocity);
  f.hdGetIntegerv(hd::kCurrentButtons, &buttons);
  drain_errors();
  reading_.position_m = frame_.position_m({position[0], position[1], position[2]});
  reading_.velocity_m_per_s = omni::Frame::velocity_m_per_s({velocity[0], velocity[1], velocity[2]});
  reading_.has_velocity = options_.use_device_velocity;
  reading_.buttons = static_cast<std::uint32_t>(buttons);

  // Periodic checks go by tick numbers, so skipped periods do not skip a check.
  if (temperature_readable_ && tick_ >= next_temperature_read_) {
    read_temperature();
    next_temperature_read_ = tick_ + temperature_ticks_;
  }
  drain_errors();

  // Leaving a hold: after a force error, at the hold's end; after warm motors, also only once
  // the thermal model has cooled (when the device has one).
  if (held_ && tick_ >= hold_until_tick_) {
    const bool still_warm =
        warm_hold_ && temperature_readable_ && published_.motor_temperature > options_.warm_motors_resume_temperature;
    if (!still_warm) {
      held_ = false;
      warm_hold_ = false;
      ramp_start_tick_ = tick_;
      ramp_ticks_ = ticks_for(options_.recovery_ramp_s, period_s_);
    }
  }
  const bool emergency = emergency_.load(std::memory_order_acquire);
  // Forces on once calibrated, unless stopping or in an emergency.
  if (calibrated_ && !forces_enabled_ && !emergency && !shutting_down_ && !stop_requested) {
    f.hdEnable(hd::kForceOutput);
    forces_enabled_ = true;
  } else if (!calibrated_ && forces_enabled_) {
    f.hdDisable(hd::kForceOutput);
    forces_enabled_ = false;
  }

  if (shutting_down_) {
    reading_status_ = fatal_status_ != DeviceStatus::kOk ? fatal_status_ : DeviceStatus::kDeviceFault;
  } else if (emergency) {
    reading_status_ = DeviceStatus::kDeviceFault;
  } else if (!calibrated_ || held_) {
    reading_status_ = DeviceStatus::kNotReady;
  } else {
    reading_status_ = DeviceStatus::kOk;
  }

  // The tick. A stop asked from outside does not run it again: the loop has been told.
  requested_n_ = {};
  TickVerdict verdict = TickVerdict::kContinue;
  if (!stop_requested) verdict = tick_fn_(tick_context_, ClockedTick{tick_, dt_s, period_s_});
  const bool ending = shutting_down_ || stop_requested || verdict == TickVerdict::kStop;
  if (verdict == TickVerdict::kStop && !shutting_down_) {
    end_reason_.store(static_cast<std::uint8_t>(EndReason::kTickStopped), std::memory_order_relaxed);
  }

  // Gate, ramp and cap; then one force command per frame, zero whenever forces are not on.
  Vec3<double> out{};
  const double scale = force_scale();
  if (reading_status_ == DeviceStatus::kOk && !ending && !emergency && scale > 0.0) {
    out = requested_n_ * scale;
    const double magnitude = std::sqrt(dot(out, out));
    // Scaled to a hair under the cap: rounding must never put the norm above the device's own
    // limit, which the library checks (HD_EXCEEDED_MAX_FORCE).
    if (magnitude > limits_.force_cap_n) out = out * (limits_.force_cap_n * (1.0 - 1e-12) / magnitude);
  }
  const Vec3<double> device_n = omni::Frame::device_force_n(out);
  const double command[3] = {device_n.x, device_n.y, device_n.z};
  f.hdSetDoublev(hd::kCurrentForce, command);
  if ((ending || emergency) && forces_enabled_) {
    f.hdDisable(hd::kForceOutput);
    forces_enabled_ = false;
  }
  f.hdEndFrame(handle_);
  in_frame_ = false;
  drain_errors();  // force errors are raised when the frame's commands reach the device

  // The callback's own duration (hdGetSchedulerTimeStamp: seconds since the tick started).
  const double elapsed_s = f.hdGetSchedulerTimeStamp();
  if (std::isfinite(elapsed_s) && elapsed_s > period_s_) overran = true;
  if (overran) {
    ++published_.overruns;
    ++consecutive_overruns_;
    if (consecutive_overruns_ >= options_.max_consecutive_overruns && !shutting_down_ && !ending) {
      shutting_down_ = true;  // the next frame is the last, and its tick hears why
      fatal_status_ = DeviceStatus::kDeviceFault;
      overrun_run_.store(static_cast<std::uint32_t>(consecutive_overruns_), std::memory_order_relaxed);
      end_reason_.store(static_cast<std::uint8_t>(EndReason::kOverruns), std::memory_order_relaxed);
    }
  } else {
    consecutive_overruns_ = 0;
  }

  published_.tick = tick_;
  published_.frames = frames_ + 1;
  published_.position_m = reading_.position_m;
  published_.force_n = out;
  published_.force_scale = reading_status_ == DeviceStatus::kOk && !ending && !emergency ? scale : 0.0;
  published_.update_rate_hz = rate_hz;
  published_.buttons = reading_.buttons;
  published_.device_status = reading_status_;
  published_.phase = ending         ? OmniPhase::kStopped
                     : !calibrated_ ? OmniPhase::kCalibrating
                     : held_        ? OmniPhase::kHeld
                     : scale < 1.0  ? OmniPhase::kRamping
                                    : OmniPhase::kRunning;
  status_.store(published_);
  ++frames_;

  if (ending) {
    callback_done_.store(true, std::memory_order_release);
    running_.store(false, std::memory_order_release);
    return hd::kCallbackDone;
  }
  return hd::kCallbackContinue;
}

DeviceStatus OmniDevice::read(DeviceReading& reading) noexcept {
  if (!in_frame_) return DeviceStatus::kNotReady;  // only inside the tick
  reading = reading_;
  return reading_status_;
}

DeviceStatus OmniDevice::write(const Vec3<double>& force_n) noexcept {
  if (!in_frame_) return DeviceStatus::kNotReady;
  if (!(std::isfinite(force_n.x) && std::isfinite(force_n.y) && std::isfinite(force_n.z))) {
    requested_n_ = {};
    return DeviceStatus::kProtocolError;
  }
  requested_n_ = force_n;
  return reading_status_;
}

// ---- messages (any thread) -------------------------------------------------------------------

std::string OmniDevice::last_error() const {
  const auto reason = static_cast<EndReason>(end_reason_.load(std::memory_order_acquire));
  const auto code = last_code_.load(std::memory_order_relaxed);
  const auto internal = last_internal_.load(std::memory_order_relaxed);
  const auto at_tick = last_code_tick_.load(std::memory_order_relaxed);
  const auto hd_error = [&] {
    return fmt::format("OpenHaptics reported {} (0x{:03x}, internal {}, {}) on tick {}: {}", hd::error_name(code), code,
                       internal, hd::to_string(hd::classify(code)), at_tick, hd::error_meaning(code));
  };
  switch (reason) {
    case EndReason::kFatalHdError: {
      std::string text = hd_error() + ".";
      if (hd::classify(code) == hd::ErrorClass::kCommunication) {
        text += " Check the cable and the port (USB or Ethernet), that no other program uses the "
                "device, and the driver's configuration (Touch_Setup).";
      }
      return text;
    }
    case EndReason::kOverruns:
      return fmt::format("the OpenHaptics scheduler overran its {:.0f} Hz period on {} ticks in a row; "
                         "the servo loop stopped with forces off. Run on a quieter or real-time "
                         "host, or lower the scheduler rate.",
                         options_.scheduler_rate_hz, overrun_run_.load(std::memory_order_relaxed));
    case EndReason::kTickStopped: return "the servo tick asked to stop; forces are off";
    case EndReason::kStopRequested:
    case EndReason::kNone: break;
  }
  if (emergency_.load(std::memory_order_acquire)) {
    return "emergency zero was requested: forces are off until the device is closed";
  }
  const OmniStatus s = status_.load();
  if (s.phase == OmniPhase::kCalibrating) {
    const auto refused = last_calibration_error_.load(std::memory_order_relaxed);
    const std::string update =
        refused != 0 ? fmt::format(" (the last calibration check or update answered {}: still calibrating)",
                                   hd::error_name(refused))
                     : std::string();
    if (s.calibration == hd::kCalibrationNeedsManualInput) {
      const int style = limits_.calibration_style;
      const char* act = style == hd::kCalibrationAuto
                            ? "move the arm slowly through its whole workspace, to its limits in every direction"
                        : style == hd::kCalibrationEncoderReset
                            ? "hold the arm in its reset pose (all links at right angles) and open the device again"
                            : "put the stylus in the inkwell";
      return fmt::format("the device needs calibrating and forces stay off until it is: {}; it calibrates "
                         "by itself once it has seen that{}",
                         act, update);
    }
    return "calibration is being checked or updated; forces stay off until hdCheckCalibration says OK" + update;
  }
  if (code != 0 && (s.phase == OmniPhase::kHeld || s.phase == OmniPhase::kRamping)) return hd_error();
  if (code != 0) return "last: " + hd_error();
  return {};
}

}  // namespace toonforce
