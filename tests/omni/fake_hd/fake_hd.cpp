// SPDX-License-Identifier: Apache-2.0
// A fake OpenHaptics HD library (libHD.so) for tests: our own code, exporting the same C
// symbols with the behaviour the reference documents (docs/OMNI.md §2.1-2.3),
// driven by a simulated Omni (§4: base-joint kinematics with L1 = L2 = 133.35 mm, 15 000
// encoder counts per revolution, and a point mass under the motor force and a hand). It lets
// tests inject every HD error, calibration states and scheduler overruns (fake_hd_control.h).
//
// It proves our binding against the documented behaviour as we read it, not against the real
// driver. Its constants are transcribed again here, independently of the backend's hd_api.hpp,
// so a typo in either shows up as a failing test.
//
// Rules it enforces (each breach raises the documented error and counts as a protocol
// violation, which tests require to stay zero): one frame per device per tick; hdEndFrame only
// after hdBeginFrame; current-state reads and force commands only inside the current device's
// frame; frame and state calls only from the scheduler thread while it runs; devices
// initialised before the scheduler starts; parameters of the right type.
//
// Several devices (tf_fake_hd_add_device): each has its own arm, calibration, limits, force,
// frame and counts; one scheduler runs every scheduled callback each tick, on its one thread;
// calls without a handle act on the current device (hdInitDevice, hdMakeCurrentDevice and
// hdBeginFrame set it), and errors carry its handle, as OpenHaptics' HDAPI documents.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "fake_hd_control.h"

#define TF_EXPORT extern "C" __attribute__((visibility("default")))

// The names below mirror the documented C API (HD_* constants, hd* functions, HDErrorInfo's
// fields), not our naming rules.
// NOLINTBEGIN(readability-identifier-naming)

namespace {

// ---- the documented ABI, transcribed independently -----------------------------------------
using HHD = unsigned int;
using HDenum = unsigned int;
using HDerror = unsigned int;
using HDboolean = unsigned char;
using HDstring = const char*;
using HDulong = unsigned long;
using HDushort = unsigned short;
using HDSchedulerHandle = unsigned long;
using HDCallbackCode = unsigned int;
using HDSchedulerCallback = HDCallbackCode (*)(void*);
struct HDErrorInfo {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
};

enum : unsigned int {
  HD_SUCCESS = 0x0000,
  HD_INVALID_ENUM = 0x0100,
  HD_INVALID_VALUE = 0x0101,
  HD_INVALID_OPERATION = 0x0102,
  HD_INVALID_INPUT_TYPE = 0x0103,
  HD_BAD_HANDLE = 0x0104,
  HD_WARM_MOTORS = 0x0200,
  HD_EXCEEDED_MAX_FORCE = 0x0201,
  HD_EXCEEDED_MAX_FORCE_IMPULSE = 0x0202,
  HD_EXCEEDED_MAX_VELOCITY = 0x0203,
  HD_FORCE_ERROR = 0x0204,
  HD_DEVICE_FAULT = 0x0300,
  HD_DEVICE_ALREADY_INITIATED = 0x0301,
  HD_COMM_ERROR = 0x0302,
  HD_COMM_CONFIG_ERROR = 0x0303,
  HD_TIMER_ERROR = 0x0304,
  HD_ILLEGAL_BEGIN = 0x0400,
  HD_ILLEGAL_END = 0x0401,
  HD_FRAME_ERROR = 0x0402,
  HD_INVALID_PRIORITY = 0x0500,
  HD_SCHEDULER_FULL = 0x0501,
  HD_INVALID_LICENSE = 0x0600,

  HD_CURRENT_BUTTONS = 0x2000,
  HD_CURRENT_SAFETY_SWITCH = 0x2001,
  HD_CURRENT_INKWELL_SWITCH = 0x2002,
  HD_CURRENT_POSITION = 0x2050,
  HD_CURRENT_VELOCITY = 0x2051,
  HD_CURRENT_JOINT_ANGLES = 0x2100,
  HD_CURRENT_GIMBAL_ANGLES = 0x2150,
  HD_VERSION = 0x2500,
  HD_DEVICE_MODEL_TYPE = 0x2501,
  HD_DEVICE_DRIVER_VERSION = 0x2502,
  HD_DEVICE_VENDOR = 0x2503,
  HD_DEVICE_SERIAL_NUMBER = 0x2504,
  HD_MAX_WORKSPACE_DIMENSIONS = 0x2550,
  HD_USABLE_WORKSPACE_DIMENSIONS = 0x2551,
  HD_TABLETOP_OFFSET = 0x2552,
  HD_INPUT_DOF = 0x2553,
  HD_OUTPUT_DOF = 0x2554,
  HD_CALIBRATION_STYLE = 0x2555,
  HD_UPDATE_RATE = 0x2600,
  HD_INSTANTANEOUS_UPDATE_RATE = 0x2601,
  HD_NOMINAL_MAX_STIFFNESS = 0x2602,
  HD_NOMINAL_MAX_FORCE = 0x2603,
  HD_NOMINAL_MAX_CONTINUOUS_FORCE = 0x2604,
  HD_MOTOR_TEMPERATURE = 0x2605,
  HD_SOFTWARE_VELOCITY_LIMIT = 0x2606,
  HD_SOFTWARE_FORCE_IMPULSE_LIMIT = 0x2607,
  HD_FORCE_RAMPING_RATE = 0x2608,
  HD_NOMINAL_MAX_DAMPING = 0x2609,
  HD_CURRENT_FORCE = 0x2700,
  HD_FORCE_OUTPUT = 0x4000,
  HD_MAX_FORCE_CLAMPING = 0x4001,
  HD_FORCE_RAMPING = 0x4002,
  HD_SOFTWARE_FORCE_LIMIT = 0x4003,
  HD_ONE_FRAME_LIMIT = 0x4004,
  HD_CALIBRATION_OK = 0x5000,
  HD_CALIBRATION_NEEDS_UPDATE = 0x5001,
  HD_CALIBRATION_NEEDS_MANUAL_INPUT = 0x5002,
};
constexpr int HD_CALIBRATION_ENCODER_RESET = 1 << 0;
constexpr int HD_CALIBRATION_AUTO = 1 << 1;  // learns as the arm moves through its workspace
constexpr int HD_CALIBRATION_INKWELL = 1 << 2;
constexpr HHD HD_INVALID_HANDLE = 0xFFFFFFFFU;
constexpr HDCallbackCode HD_CALLBACK_DONE = 0;

// ---- the simulated Omni -----------------------------------------------------------------------
constexpr double kPi = 3.14159265358979323846;
constexpr double kL1 = 0.13335;                          // [m] upper arm (OMNI.md §4.2, literature value)
constexpr double kL2 = 0.13335;                          // [m] forearm to the gimbal centre
constexpr double kCountsPerRad = 15000.0 / (2.0 * kPi);  // base encoders (§1.1)
constexpr double kMass = 0.15;                           // [kg] apparent inertia plus the fingers holding it
constexpr double kDeviceDamping = 0.3;                   // [N s/m] back-drive friction, viscous
constexpr double kUncalibratedOffsetMm = 20.0;           // an uncalibrated device reports garbage
constexpr double kVelocityCutoffHz = 100.0;              // the library's own velocity smoothing
constexpr double kAutoCalibrationSweepRad = 0.5;         // each base joint's sweep that teaches auto calibration
constexpr int kMaxCallbacks = 32;
constexpr std::size_t kMaxDevices = 4;
constexpr int kMaxSyncJobs = 16;
constexpr std::size_t kErrorStackDepth = 64;
const double kUsableWorkspace[6] = {-80.0, -65.0, -40.0, 80.0, 55.0, 30.0};  // [mm]
const double kMaxWorkspace[6] = {-105.0, -90.0, -60.0, 105.0, 80.0, 50.0};   // [mm]

using V3 = std::array<double, 3>;

/// Base frame (z up at the shoulder, x toward the user at q1 = 0) from the absolute-elbow
/// joint angles (OMNI.md §4.3).
V3 forward(const V3& q) {
  const double r = kL1 * std::cos(q[1]) + kL2 * std::sin(q[2]);
  return {r * std::cos(q[0]), r * std::sin(q[0]), kL1 * std::sin(q[1]) - kL2 * std::cos(q[2])};
}

/// The elbow-up inverse of forward(): upper arm at angle q2 in the (r, z) plane, forearm at
/// q3 - pi/2.
V3 inverse(const V3& p) {
  const double q1 = std::atan2(p[1], p[0]);
  const double r = std::hypot(p[0], p[1]);
  const double d2 = r * r + p[2] * p[2];
  const double c = std::clamp((d2 - kL1 * kL1 - kL2 * kL2) / (2.0 * kL1 * kL2), -1.0, 1.0);
  const double relative = -std::acos(c);  // forearm direction minus upper-arm direction
  const double q2 = std::atan2(p[2], r) - std::atan2(kL2 * std::sin(relative), kL1 + kL2 * std::cos(relative));
  return {q1, q2, q2 + relative + kPi / 2.0};
}

// The device frame (x right, y up, z toward the user; origin at the neutral pose q = 0) and
// the base frame (x toward the user, y right, z up).
const V3 kNeutralBase = forward({0.0, 0.0, 0.0});
V3 base_from_device(const V3& d_m) {
  return {kNeutralBase[0] + d_m[2], kNeutralBase[1] + d_m[0], kNeutralBase[2] + d_m[1]};
}
V3 device_from_base(const V3& b) { return {b[1] - kNeutralBase[1], b[2] - kNeutralBase[2], b[0] - kNeutralBase[0]}; }
double norm(const V3& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

struct Injection {
  std::size_t device;  // index of the device it belongs to
  unsigned int code;
  int internal;
  int where;
  unsigned long remaining;
};

struct Callback {
  HDSchedulerHandle id;
  HDSchedulerCallback fn;
  void* data;
  HDushort priority;
  bool active;
};

struct SyncJob {
  HDSchedulerCallback fn;
  void* data;
  bool done;
};

/// One simulated device: its configuration, its arm, its frame and its counts. OpenHaptics
/// keeps these per device (HHD); calls without a handle act on the current device.
struct Dev {
  // configuration (what Touch_Setup would have named it, and what it reports)
  std::string name = "Default Device";
  std::string serial = "FAKE-0001";
  double max_force_n = 3.3;  // widely quoted, unverified datasheet values (OMNI.md §3)
  double max_continuous_force_n = 0.88;
  double stiffness_n_per_mm = 1.26;
  double damping_n_s_per_mm = 0.004;
  double velocity_limit_mm_per_s = 1000.0;
  double impulse_limit_n_per_ms = 3.0;
  double ramping_rate_n_per_s = 10.0;
  unsigned int calibration = HD_CALIBRATION_OK;
  int calibration_styles = HD_CALIBRATION_INKWELL;
  unsigned int calibration_update_error = HD_INVALID_OPERATION;
  std::string model = "Touch (toonforce fake libHD)";
  bool inkwell = false;
  V3 sweep_min{};  // joint angles seen while auto calibration waits for the arm to move
  V3 sweep_max{};
  bool sweeping = false;
  int buttons = 0;
  bool temperature_supported = true;
  double temperature_override = -1.0;

  // device
  bool initialized = false;
  HHD handle = 1;
  unsigned long init_calls = 0;
  bool force_output = false;
  bool clamping = false;
  bool ramping = true;
  bool software_force_limit = true;
  bool one_frame_limit = true;
  unsigned long frames_this_tick = 0;

  // frame
  bool in_frame = false;
  bool force_set = false;
  V3 command{};
  V3 previous_command{};
  V3 applied{};
  double ramp_level_n = 1e9;  // the library's own ramp after an error (HD_FORCE_RAMPING)

  // simulation (device frame, metres)
  bool pinned = true;
  V3 hand_target{};
  double hand_k = 0.0;
  double hand_b = 0.0;
  V3 position{};
  V3 velocity{};
  V3 reported_mm{};
  V3 previous_reported_mm{};
  V3 reported_velocity_mm{};
  V3 joints{};
  bool have_reported = false;
  double temperature = 0.0;

  // statistics
  unsigned long frames = 0;
  double max_force_norm = 0.0;
  unsigned long enabled_uncalibrated = 0;
  unsigned long nonzero_uncalibrated = 0;
  unsigned long calibration_checks = 0;
  unsigned long calibration_updates = 0;
  unsigned long calibration_update_errors = 0;
  unsigned long calibration_updates_in_frame = 0;
};

struct Fake {
  std::mutex mu;
  std::condition_variable cv_step;
  std::condition_variable cv_done;

  // the library
  std::string version = "3.4.0";
  double callback_time_s = 50e-6;
  bool manual = false;
  double rate_hz = 1000.0;
  // The devices, fixed storage (a tick never allocates); handle = index + 1. `named`: once the
  // test configured devices, hdInitDevice matches names; before, any name opens device 0.
  std::array<Dev, kMaxDevices> devices{};
  std::size_t device_count = 1;
  bool named = false;
  std::size_t current = 0;   // hdMakeCurrentDevice / hdBeginFrame / hdInitDevice
  std::size_t selected = 0;  // what the tf_fake_hd_* controls act on
  Fake() {
    for (std::size_t k = 0; k < kMaxDevices; ++k) devices[k].handle = static_cast<HHD>(k + 1);
  }
  Dev& current_dev() { return devices[current]; }
  Dev& selected_dev() { return devices[selected]; }
  // The error stack, fixed size so the servo thread never allocates (the oldest drop off).
  std::array<HDErrorInfo, kErrorStackDepth> errors{};
  std::size_t error_count = 0;
  std::vector<Injection> injections;

  // scheduler
  std::thread thread;
  std::thread::id scheduler_thread{};
  bool running = false;
  bool stop = false;
  unsigned long pending_steps = 0;
  unsigned int pending_overrun = 0;
  std::array<Callback, kMaxCallbacks> callbacks{};
  int callback_count = 0;  // slots used (inactive ones stay until reset)
  std::array<SyncJob*, kMaxSyncJobs> sync_jobs{};
  int sync_count = 0;
  HDSchedulerHandle next_callback = 1;
  std::chrono::steady_clock::time_point tick_start{};
  double tick_dt_s = 1e-3;

  // statistics
  unsigned long ticks = 0;
  double sim_time_s = 0.0;
  unsigned long violations = 0;
  unsigned int last_violation = 0;
  char last_violation_call[64] = {};
  unsigned long errors_raised = 0;
  unsigned long disable_device_calls = 0;
};

Fake& fake() {
  static Fake* f = new Fake();  // never destroyed: the scheduler thread may outlive statics
  return *f;
}

// ---- helpers (mu held) --------------------------------------------------------------------

void push_error(Fake& f, unsigned int code, int internal = 0) {
  if (f.error_count == kErrorStackDepth) {
    std::move(f.errors.begin() + 1, f.errors.end(), f.errors.begin());
    --f.error_count;
  }
  f.errors[f.error_count++] = HDErrorInfo{code, internal, f.current_dev().handle};  // the device it concerns
  ++f.errors_raised;
}

bool is_force_error(unsigned int code) { return code >= HD_WARM_MOTORS && code <= HD_FORCE_ERROR; }

void violation(Fake& f, unsigned int code, const char* call) {
  ++f.violations;
  f.last_violation = code;
  // Truncated copy (a name longer than the buffer is cut, never overrun).
  const std::size_t n = std::min(std::strlen(call), sizeof f.last_violation_call - 1);
  std::memcpy(f.last_violation_call, call, n);
  f.last_violation_call[n] = '\0';
  if (code != TF_FAKE_HD_WRONG_THREAD) push_error(f, code);
}

/// Frame and state calls belong to the scheduler thread while it runs (the documented way to
/// reach the servo loop from elsewhere is hdScheduleSynchronous).
void check_thread(Fake& f, const char* call) {
  if (f.running && std::this_thread::get_id() != f.scheduler_thread) {
    violation(f, TF_FAKE_HD_WRONG_THREAD, call);
  }
}

/// Raises the injections due at `where`; true when one of them was a force error (the
/// library then zeroes the motors and ramps back).
bool raise_injected(Fake& f, Dev& d, int where) {
  bool force_error = false;
  for (Injection& i : f.injections) {
    if (i.where == where && i.remaining > 0 && &f.devices[i.device] == &d) {
      push_error(f, i.code, i.internal);
      --i.remaining;
      if (is_force_error(i.code)) {
        force_error = true;
        d.applied = {};
        d.ramp_level_n = 0.0;
      }
    }
  }
  return force_error;
}

double motor_temperature(const Dev& d) {
  return d.temperature_override >= 0.0 ? d.temperature_override : d.temperature;
}

/// What a person's actions do to a device that waits for manual input: docking the stylus in
/// the inkwell, or sweeping the arm through its workspace (auto style), is what the device
/// needs before an update can succeed.
void follow_person(Dev& d) {
  if (d.calibration != HD_CALIBRATION_NEEDS_MANUAL_INPUT) {
    d.sweeping = false;
    return;
  }
  if ((d.calibration_styles & HD_CALIBRATION_INKWELL) != 0 && d.inkwell) {
    d.calibration = HD_CALIBRATION_NEEDS_UPDATE;
    return;
  }
  if ((d.calibration_styles & HD_CALIBRATION_AUTO) != 0) {
    const V3 q = inverse(base_from_device(d.position));
    if (!d.sweeping) {
      d.sweep_min = q;
      d.sweep_max = q;
      d.sweeping = true;
    }
    bool swept = true;
    for (std::size_t i = 0; i < 3; ++i) {
      d.sweep_min[i] = std::min(d.sweep_min[i], q[i]);
      d.sweep_max[i] = std::max(d.sweep_max[i], q[i]);
      swept = swept && d.sweep_max[i] - d.sweep_min[i] >= kAutoCalibrationSweepRad;
    }
    if (swept) {
      d.calibration = HD_CALIBRATION_NEEDS_UPDATE;
      d.sweeping = false;
    }
  }
}

/// Reads the device as the encoders see it: quantised joint angles through the kinematics.
void latch_reading(const Fake& f, Dev& d) {
  const V3 q = inverse(base_from_device(d.position));
  for (std::size_t i = 0; i < 3; ++i) d.joints[i] = std::round(q[i] * kCountsPerRad) / kCountsPerRad;
  const V3 p = device_from_base(forward(d.joints));
  const double offset = d.calibration == HD_CALIBRATION_OK ? 0.0 : kUncalibratedOffsetMm;
  for (std::size_t i = 0; i < 3; ++i) d.reported_mm[i] = p[i] * 1000.0 + offset;
  if (d.have_reported) {
    const double a = f.tick_dt_s / (f.tick_dt_s + 1.0 / (2.0 * kPi * kVelocityCutoffHz));
    for (std::size_t i = 0; i < 3; ++i) {
      const double raw = (d.reported_mm[i] - d.previous_reported_mm[i]) / f.tick_dt_s;
      d.reported_velocity_mm[i] += a * (raw - d.reported_velocity_mm[i]);
    }
  }
  d.previous_reported_mm = d.reported_mm;
  d.have_reported = true;
}

/// Advances the simulation over one tick with the motor force applied at the last frame (a
/// zero-order hold, as a real amplifier does).
void simulate(Dev& d, double dt) {
  if (d.pinned) {
    for (std::size_t i = 0; i < 3; ++i) {
      d.velocity[i] = (d.hand_target[i] - d.position[i]) / dt;
      d.position[i] = d.hand_target[i];
    }
  } else {
    constexpr int kSubsteps = 10;
    const double h = dt / kSubsteps;
    for (int s = 0; s < kSubsteps; ++s) {
      for (std::size_t i = 0; i < 3; ++i) {
        const double force =
            d.applied[i] + d.hand_k * (d.hand_target[i] - d.position[i]) - (d.hand_b + kDeviceDamping) * d.velocity[i];
        d.velocity[i] += force / kMass * h;  // semi-implicit Euler
        d.position[i] += d.velocity[i] * h;
      }
    }
  }
  // Motor thermal model: warms toward (|F| / F_continuous)^2 with a 60 s time constant, so
  // the peak force can be held for seconds, not minutes.
  const double load = norm(d.applied) / d.max_continuous_force_n;
  d.temperature += (load * load - d.temperature) * (dt / (60.0 + dt));
}

// ---- the scheduler ----------------------------------------------------------------------------

void run_tick(Fake& f, std::unique_lock<std::mutex>& lock) {
  const unsigned int periods = f.pending_overrun > 0 ? f.pending_overrun : 1;
  f.pending_overrun = 0;
  f.tick_dt_s = periods / f.rate_hz;
  for (std::size_t k = 0; k < f.device_count; ++k) {  // every arm moves, opened or not
    Dev& d = f.devices[k];
    simulate(d, f.tick_dt_s);
    follow_person(d);
    d.frames_this_tick = 0;
  }
  f.sim_time_s += f.tick_dt_s;
  ++f.ticks;
  f.tick_start = std::chrono::steady_clock::now();
  // Active callbacks by decreasing priority (OMNI.md §2.2 item 4); fixed arrays, so a tick
  // allocates nothing and tests can count the backend's allocations on this thread.
  std::array<Callback, kMaxCallbacks> due{};
  int due_count = 0;
  for (int i = 0; i < f.callback_count; ++i) {
    if (!f.callbacks[static_cast<std::size_t>(i)].active) continue;
    int at = due_count++;
    while (at > 0 &&
           due[static_cast<std::size_t>(at - 1)].priority < f.callbacks[static_cast<std::size_t>(i)].priority) {
      due[static_cast<std::size_t>(at)] = due[static_cast<std::size_t>(at - 1)];
      --at;
    }
    due[static_cast<std::size_t>(at)] = f.callbacks[static_cast<std::size_t>(i)];
  }
  std::array<SyncJob*, kMaxSyncJobs> jobs = f.sync_jobs;
  const int job_count = f.sync_count;

  lock.unlock();  // callbacks call back into the library
  std::array<bool, kMaxCallbacks> finished{};
  for (int i = 0; i < due_count; ++i) {
    const Callback& c = due[static_cast<std::size_t>(i)];
    finished[static_cast<std::size_t>(i)] = c.fn(c.data) == HD_CALLBACK_DONE;
  }
  std::array<bool, kMaxSyncJobs> job_done{};
  for (int i = 0; i < job_count; ++i) {
    SyncJob* job = jobs[static_cast<std::size_t>(i)];
    job_done[static_cast<std::size_t>(i)] = job->fn(job->data) == HD_CALLBACK_DONE;
  }
  lock.lock();

  for (int i = 0; i < due_count; ++i) {
    if (!finished[static_cast<std::size_t>(i)]) continue;
    for (int k = 0; k < f.callback_count; ++k) {
      if (f.callbacks[static_cast<std::size_t>(k)].id == due[static_cast<std::size_t>(i)].id) {
        f.callbacks[static_cast<std::size_t>(k)].active = false;
      }
    }
  }
  bool any_done = false;
  for (int i = 0; i < job_count; ++i) {
    if (!job_done[static_cast<std::size_t>(i)]) continue;
    SyncJob* job = jobs[static_cast<std::size_t>(i)];
    job->done = true;
    any_done = true;
    for (int k = 0; k < f.sync_count; ++k) {
      if (f.sync_jobs[static_cast<std::size_t>(k)] == job) {
        for (int m = k + 1; m < f.sync_count; ++m)
          f.sync_jobs[static_cast<std::size_t>(m - 1)] = f.sync_jobs[static_cast<std::size_t>(m)];
        --f.sync_count;
        break;
      }
    }
  }
  for (std::size_t k = 0; k < f.device_count; ++k) {
    Dev& d = f.devices[k];
    if (d.in_frame) {  // a callback left its frame open
      f.current = k;
      violation(f, HD_FRAME_ERROR, "frame left open");
      d.in_frame = false;
    }
  }
  if (any_done) f.cv_done.notify_all();
}

void scheduler_main() {
  Fake& f = fake();
  std::unique_lock lock(f.mu);
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  while (!f.stop) {
    if (f.manual) {
      f.cv_step.wait(lock, [&] { return f.stop || f.pending_steps > 0; });
      if (f.stop) break;
      run_tick(f, lock);
      if (--f.pending_steps == 0) f.cv_done.notify_all();
      continue;
    }
    const long period_ns = std::lround(1e9 / f.rate_hz);
    next.tv_nsec += period_ns;
    while (next.tv_nsec >= 1000000000L) {
      next.tv_nsec -= 1000000000L;
      ++next.tv_sec;
    }
    lock.unlock();
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
    lock.lock();
    if (!f.stop) run_tick(f, lock);
  }
}

V3 to_v3(const double* p) { return {p[0], p[1], p[2]}; }

/// The initialised device of a handle (handle = index + 1), or null.
Dev* by_handle(Fake& f, HHD h) {
  if (h == 0 || h > f.device_count) return nullptr;
  Dev& d = f.devices[h - 1];
  return d.initialized ? &d : nullptr;
}

}  // namespace

// ---- the HD API ---------------------------------------------------------------------------

TF_EXPORT HHD hdInitDevice(HDstring config_name) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  // HD_DEFAULT_DEVICE (null) is the first configured device; before the test configured any,
  // every name opens the one simulated device.
  std::size_t index = 0;
  if (f.named && config_name != nullptr && config_name[0] != '\0') {
    index = f.device_count;
    for (std::size_t k = 0; k < f.device_count; ++k) {
      if (f.devices[k].name == config_name) index = k;
    }
    if (index == f.device_count) {
      // No device of that name is configured. The reference does not say which code the real
      // library raises; the configuration is what lacks it, so: HD_COMM_CONFIG_ERROR.
      push_error(f, HD_COMM_CONFIG_ERROR);
      return HD_INVALID_HANDLE;
    }
  }
  // Devices are initialised before the one scheduler starts (OMNI.md §2.2 item 5).
  if (f.running) violation(f, TF_FAKE_HD_INIT_WHILE_RUNNING, "hdInitDevice while the scheduler runs");
  Dev& d = f.devices[index];
  ++d.init_calls;
  for (Injection& i : f.injections) {
    if (i.where == TF_FAKE_HD_AT_INIT && i.remaining > 0 && i.device == index) {
      --i.remaining;
      push_error(f, i.code, i.internal);
      return HD_INVALID_HANDLE;
    }
  }
  if (d.initialized) {
    push_error(f, HD_DEVICE_ALREADY_INITIATED);
    return HD_INVALID_HANDLE;
  }
  d.initialized = true;
  f.current = index;  // the device just opened is the current one
  return d.handle;
}

TF_EXPORT void hdDisableDevice(HHD device) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  ++f.disable_device_calls;
  Dev* d = by_handle(f, device);
  if (d == nullptr) {
    violation(f, HD_BAD_HANDLE, "hdDisableDevice");
    return;
  }
  d->initialized = false;
  d->force_output = false;
}

TF_EXPORT void hdMakeCurrentDevice(HHD device) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (by_handle(f, device) == nullptr) return violation(f, HD_BAD_HANDLE, "hdMakeCurrentDevice");
  f.current = device - 1;
}

TF_EXPORT HHD hdGetCurrentDevice() {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  return d.initialized ? d.handle : HD_INVALID_HANDLE;
}

TF_EXPORT void hdBeginFrame(HHD device) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  check_thread(f, "hdBeginFrame");
  if (by_handle(f, device) == nullptr) return violation(f, HD_BAD_HANDLE, "hdBeginFrame");
  f.current = device - 1;  // hdBeginFrame makes its device current
  Dev& d = f.current_dev();
  if (d.in_frame || (d.one_frame_limit && d.frames_this_tick > 0)) {
    return violation(f, HD_ILLEGAL_BEGIN, "hdBeginFrame");
  }
  d.in_frame = true;
  d.force_set = false;
  latch_reading(f, d);
  raise_injected(f, d, TF_FAKE_HD_AT_BEGIN);
}

TF_EXPORT void hdEndFrame(HHD device) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  check_thread(f, "hdEndFrame");
  if (by_handle(f, device) == nullptr) return violation(f, HD_BAD_HANDLE, "hdEndFrame");
  // The frame ended is the handle's, whichever device was current (nested frames of two
  // devices); it becomes current so that its errors carry its handle.
  f.current = device - 1;
  Dev& d = f.current_dev();
  if (!d.in_frame) return violation(f, HD_ILLEGAL_END, "hdEndFrame");
  d.in_frame = false;
  ++d.frames;
  ++d.frames_this_tick;

  const V3 command = d.force_set ? d.command : V3{};
  const double magnitude = norm(command);
  const bool calibrated = d.calibration == HD_CALIBRATION_OK;
  if (d.force_output && !calibrated) ++d.enabled_uncalibrated;
  if (magnitude > 0.0 && !calibrated) ++d.nonzero_uncalibrated;

  // The library's safety checks (OMNI.md §2.3), then the motors.
  V3 applied = command;
  bool force_error = false;
  if (d.force_output) {
    if (magnitude > d.max_force_n) {
      if (d.clamping) {
        for (double& c : applied) c *= d.max_force_n / magnitude;
      } else {
        push_error(f, HD_EXCEEDED_MAX_FORCE);
        force_error = true;
      }
    }
    const V3 step{command[0] - d.previous_command[0], command[1] - d.previous_command[1],
                  command[2] - d.previous_command[2]};
    // A kick is a large change toward a force; dropping to zero is the safe direction.
    if (d.software_force_limit && magnitude > 1e-9 && norm(step) / (f.tick_dt_s * 1000.0) > d.impulse_limit_n_per_ms) {
      push_error(f, HD_EXCEEDED_MAX_FORCE_IMPULSE);
      force_error = true;
    }
    if (d.software_force_limit && norm(d.reported_velocity_mm) > d.velocity_limit_mm_per_s) {
      push_error(f, HD_EXCEEDED_MAX_VELOCITY);
      force_error = true;
    }
    // The thermal model: warm motors refuse force until they cool.
    if (magnitude > 0.0 && motor_temperature(d) >= 1.0) {
      push_error(f, HD_WARM_MOTORS);
      force_error = true;
    }
  }
  if (raise_injected(f, d, TF_FAKE_HD_AT_END)) force_error = true;
  if (force_error) d.ramp_level_n = 0.0;
  if (!d.force_output || force_error) {
    applied = {};
  } else if (d.ramping) {
    d.ramp_level_n = std::min(d.ramp_level_n + d.ramping_rate_n_per_s * f.tick_dt_s, 1e9);
    const double n = norm(applied);
    if (n > d.ramp_level_n) {
      for (double& c : applied) c *= d.ramp_level_n / n;
    }
  }
  d.applied = applied;
  d.previous_command = command;
}

TF_EXPORT HDErrorInfo hdGetError() {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  if (f.error_count == 0) return HDErrorInfo{HD_SUCCESS, 0, d.handle};
  return f.errors[--f.error_count];  // most recent first
}

TF_EXPORT HDstring hdGetErrorString(HDerror code) {
  switch (code) {
    case HD_SUCCESS: return "No error";
    case HD_COMM_ERROR: return "Communication error (fake)";
    case HD_WARM_MOTORS: return "Motors are warm (fake)";
    default: return "Error reported by the fake libHD";
  }
}

namespace {
bool* capability(Dev& d, HDenum cap) {
  switch (cap) {
    case HD_FORCE_OUTPUT: return &d.force_output;
    case HD_MAX_FORCE_CLAMPING: return &d.clamping;
    case HD_FORCE_RAMPING: return &d.ramping;
    case HD_SOFTWARE_FORCE_LIMIT: return &d.software_force_limit;
    case HD_ONE_FRAME_LIMIT: return &d.one_frame_limit;
    default: return nullptr;
  }
}
}  // namespace

TF_EXPORT void hdEnable(HDenum cap) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  check_thread(f, "hdEnable");
  bool* c = capability(f.current_dev(), cap);
  if (c == nullptr) return violation(f, HD_INVALID_ENUM, "hdEnable");
  if (cap == HD_FORCE_OUTPUT && !*c) d.ramp_level_n = 0.0;  // ramps in after (re)enabling
  *c = true;
}

TF_EXPORT void hdDisable(HDenum cap) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  check_thread(f, "hdDisable");
  bool* c = capability(f.current_dev(), cap);
  if (c == nullptr) return violation(f, HD_INVALID_ENUM, "hdDisable");
  *c = false;
}

TF_EXPORT HDboolean hdIsEnabled(HDenum cap) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  bool* c = capability(f.current_dev(), cap);
  if (c == nullptr) {
    violation(f, HD_INVALID_ENUM, "hdIsEnabled");
    return 0;
  }
  return *c ? 1 : 0;
}

namespace {
/// Current-state parameters exist only between hdBeginFrame and hdEndFrame.
bool state_read_ok(Fake& f, const char* call) {
  const Dev& d = f.current_dev();
  check_thread(f, call);
  if (!d.in_frame) {
    violation(f, HD_INVALID_OPERATION, call);
    return false;
  }
  return true;
}
}  // namespace

TF_EXPORT void hdGetDoublev(HDenum name, double* values) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  switch (name) {
    case HD_CURRENT_POSITION:
      if (state_read_ok(f, "hdGetDoublev(HD_CURRENT_POSITION)"))
        std::copy(d.reported_mm.begin(), d.reported_mm.end(), values);
      return;
    case HD_CURRENT_VELOCITY:
      if (state_read_ok(f, "hdGetDoublev(HD_CURRENT_VELOCITY)")) {
        std::copy(d.reported_velocity_mm.begin(), d.reported_velocity_mm.end(), values);
      }
      return;
    case HD_CURRENT_JOINT_ANGLES:
      if (state_read_ok(f, "hdGetDoublev(HD_CURRENT_JOINT_ANGLES)"))
        std::copy(d.joints.begin(), d.joints.end(), values);
      return;
    case HD_CURRENT_GIMBAL_ANGLES:
      if (state_read_ok(f, "hdGetDoublev(HD_CURRENT_GIMBAL_ANGLES)")) std::fill(values, values + 3, 0.0);
      return;
    case HD_INSTANTANEOUS_UPDATE_RATE:
      if (state_read_ok(f, "hdGetDoublev(HD_INSTANTANEOUS_UPDATE_RATE)")) values[0] = 1.0 / f.tick_dt_s;
      return;
    case HD_UPDATE_RATE: values[0] = f.rate_hz; return;
    case HD_USABLE_WORKSPACE_DIMENSIONS: std::copy(kUsableWorkspace, kUsableWorkspace + 6, values); return;
    case HD_MAX_WORKSPACE_DIMENSIONS: std::copy(kMaxWorkspace, kMaxWorkspace + 6, values); return;
    case HD_TABLETOP_OFFSET: values[0] = 100.0; return;
    case HD_NOMINAL_MAX_FORCE: values[0] = d.max_force_n; return;
    case HD_NOMINAL_MAX_CONTINUOUS_FORCE: values[0] = d.max_continuous_force_n; return;
    case HD_NOMINAL_MAX_STIFFNESS: values[0] = d.stiffness_n_per_mm; return;
    case HD_NOMINAL_MAX_DAMPING: values[0] = d.damping_n_s_per_mm; return;
    case HD_SOFTWARE_VELOCITY_LIMIT: values[0] = d.velocity_limit_mm_per_s; return;
    case HD_SOFTWARE_FORCE_IMPULSE_LIMIT: values[0] = d.impulse_limit_n_per_ms; return;
    case HD_FORCE_RAMPING_RATE: values[0] = d.ramping_rate_n_per_s; return;
    case HD_MOTOR_TEMPERATURE:
      // A device without the thermal model answers like any unsupported parameter; asking is
      // not a breach of the rules.
      if (!d.temperature_supported) return push_error(f, HD_INVALID_ENUM);
      std::fill(values, values + 3, motor_temperature(d));  // three base motors
      return;
    case HD_CURRENT_BUTTONS:
    case HD_INPUT_DOF:
    case HD_OUTPUT_DOF:
    case HD_CALIBRATION_STYLE:
    case HD_CURRENT_INKWELL_SWITCH: return violation(f, HD_INVALID_INPUT_TYPE, "hdGetDoublev");
    default: return violation(f, HD_INVALID_ENUM, "hdGetDoublev");
  }
}

TF_EXPORT void hdGetIntegerv(HDenum name, int* values) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  switch (name) {
    case HD_CURRENT_BUTTONS:
      if (state_read_ok(f, "hdGetIntegerv(HD_CURRENT_BUTTONS)")) values[0] = d.buttons;
      return;
    case HD_INPUT_DOF: values[0] = 6; return;
    case HD_OUTPUT_DOF: values[0] = 3; return;
    case HD_CALIBRATION_STYLE: values[0] = d.calibration_styles; return;
    case HD_CURRENT_INKWELL_SWITCH: return violation(f, HD_INVALID_INPUT_TYPE, "hdGetIntegerv(INKWELL)");
    default: return violation(f, HD_INVALID_ENUM, "hdGetIntegerv");
  }
}

TF_EXPORT void hdGetBooleanv(HDenum name, HDboolean* values) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  switch (name) {
    case HD_CURRENT_INKWELL_SWITCH:
      if (state_read_ok(f, "hdGetBooleanv(HD_CURRENT_INKWELL_SWITCH)")) values[0] = d.inkwell ? 1 : 0;
      return;
    case HD_CURRENT_SAFETY_SWITCH:
      if (state_read_ok(f, "hdGetBooleanv(HD_CURRENT_SAFETY_SWITCH)")) values[0] = 1;
      return;
    default: return violation(f, HD_INVALID_ENUM, "hdGetBooleanv");
  }
}

TF_EXPORT HDstring hdGetString(HDenum name) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  switch (name) {
    case HD_VERSION: return f.version.c_str();
    case HD_DEVICE_MODEL_TYPE: return d.model.c_str();
    case HD_DEVICE_DRIVER_VERSION: return "0.0-fake";
    case HD_DEVICE_VENDOR: return "toonforce test double";
    case HD_DEVICE_SERIAL_NUMBER: return d.serial.c_str();
    default: violation(f, HD_INVALID_ENUM, "hdGetString"); return nullptr;
  }
}

TF_EXPORT void hdSetDoublev(HDenum name, const double* values) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  switch (name) {
    case HD_CURRENT_FORCE: {
      check_thread(f, "hdSetDoublev(HD_CURRENT_FORCE)");
      if (!d.in_frame) return violation(f, HD_INVALID_OPERATION, "hdSetDoublev(HD_CURRENT_FORCE)");
      d.command = to_v3(values);
      d.force_set = true;
      d.max_force_norm = std::max(d.max_force_norm, norm(d.command));
      return;
    }
    case HD_FORCE_RAMPING_RATE: d.ramping_rate_n_per_s = values[0]; return;
    case HD_SOFTWARE_VELOCITY_LIMIT: d.velocity_limit_mm_per_s = values[0]; return;
    case HD_SOFTWARE_FORCE_IMPULSE_LIMIT: d.impulse_limit_n_per_ms = values[0]; return;
    default: return violation(f, HD_INVALID_ENUM, "hdSetDoublev");
  }
}

TF_EXPORT HDenum hdCheckCalibration() {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  ++d.calibration_checks;
  follow_person(d);  // a person who docked the stylus before the scheduler ran is seen too
  return d.calibration;
}

TF_EXPORT void hdUpdateCalibration(HDenum style) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.current_dev();
  ++d.calibration_updates;
  if (d.in_frame) ++d.calibration_updates_in_frame;
  if ((static_cast<int>(style) & d.calibration_styles) == 0 || (style & (style - 1)) != 0) {
    return violation(f, HD_INVALID_VALUE, "hdUpdateCalibration");
  }
  for (Injection& i : f.injections) {
    if (i.where == TF_FAKE_HD_AT_CALIBRATION_UPDATE && i.remaining > 0 && &f.devices[i.device] == &d) {
      --i.remaining;
      ++d.calibration_update_errors;
      push_error(f, i.code, i.internal);
      return;
    }
  }
  follow_person(d);
  const bool reset_pose = style == HD_CALIBRATION_ENCODER_RESET;
  if (d.calibration == HD_CALIBRATION_NEEDS_MANUAL_INPUT && !reset_pose) {
    // Nothing to update from yet: the device refuses (the vendor's example and the ROS node
    // update only on NEEDS_UPDATE; sawSensablePhantom reports such an error as "calibration
    // failed" and carries on).
    ++d.calibration_update_errors;
    push_error(f, d.calibration_update_error);
    return;
  }
  if (d.calibration != HD_CALIBRATION_OK) {
    d.calibration = HD_CALIBRATION_OK;
    // The offset vanishes at once; the library's velocity filter starts afresh rather than
    // reporting the jump as motion.
    d.have_reported = false;
    d.reported_velocity_mm = {};
  }
}

TF_EXPORT void hdSetSchedulerRate(HDulong rate_hz) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (rate_hz != 500 && rate_hz != 1000 && rate_hz != 1600 && rate_hz != 2000) {
    return push_error(f, HD_INVALID_VALUE);  // the rates the reference guide lists
  }
  f.rate_hz = static_cast<double>(rate_hz);
}

TF_EXPORT void hdStartScheduler() {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (f.running) return;
  for (Injection& i : f.injections) {
    if (i.where == TF_FAKE_HD_AT_START && i.remaining > 0) {
      --i.remaining;
      push_error(f, i.code, i.internal);
      return;
    }
  }
  for (std::size_t k = 0; k < f.device_count; ++k) {
    // Starting the one scheduler enables forces on every device (OMNI.md §2.2 item 5).
    Dev& d = f.devices[k];
    if (!d.initialized) continue;
    d.force_output = true;
    d.ramp_level_n = 0.0;
  }
  f.stop = false;
  f.running = true;
  f.pending_steps = 0;
  f.thread = std::thread(scheduler_main);
  f.scheduler_thread = f.thread.get_id();
}

TF_EXPORT void hdStopScheduler() {
  Fake& f = fake();
  std::thread thread;
  {
    std::lock_guard lock(f.mu);
    if (!f.running) return;
    f.stop = true;
    f.running = false;
    for (Dev& d : f.devices) d.force_output = false;
    thread = std::move(f.thread);
  }
  f.cv_step.notify_all();
  if (thread.joinable()) thread.join();
  std::lock_guard lock(f.mu);
  f.pending_steps = 0;
  f.cv_done.notify_all();
}

TF_EXPORT HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback callback, void* user_data, HDushort priority) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (f.callback_count >= kMaxCallbacks) {
    push_error(f, HD_SCHEDULER_FULL);
    return 0;
  }
  f.callbacks[static_cast<std::size_t>(f.callback_count++)] =
      Callback{f.next_callback, callback, user_data, priority, true};
  return f.next_callback++;
}

TF_EXPORT void hdScheduleSynchronous(HDSchedulerCallback callback, void* user_data, HDushort priority) {
  static_cast<void>(priority);
  Fake& f = fake();
  std::unique_lock lock(f.mu);
  if (!f.running) {
    lock.unlock();
    while (callback(user_data) != HD_CALLBACK_DONE) {
    }
    return;
  }
  if (f.sync_count >= kMaxSyncJobs) return push_error(f, HD_SCHEDULER_FULL);
  SyncJob job{callback, user_data, false};
  f.sync_jobs[static_cast<std::size_t>(f.sync_count++)] = &job;
  f.cv_done.wait(lock, [&] { return job.done || !f.running; });
  if (!job.done) {  // the scheduler stopped first: forget the job
    for (int k = 0; k < f.sync_count; ++k) {
      if (f.sync_jobs[static_cast<std::size_t>(k)] == &job) {
        for (int m = k + 1; m < f.sync_count; ++m)
          f.sync_jobs[static_cast<std::size_t>(m - 1)] = f.sync_jobs[static_cast<std::size_t>(m)];
        --f.sync_count;
        break;
      }
    }
  }
}

TF_EXPORT void hdUnschedule(HDSchedulerHandle handle) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  for (int i = 0; i < f.callback_count; ++i) {
    if (f.callbacks[static_cast<std::size_t>(i)].id == handle) f.callbacks[static_cast<std::size_t>(i)].active = false;
  }
}

#ifndef TF_FAKE_HD_WITHOUT_SCHEDULER_TIMESTAMP
TF_EXPORT double hdGetSchedulerTimeStamp() {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (f.manual) return f.callback_time_s;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - f.tick_start).count();
}
#endif

// ---- test control ---------------------------------------------------------------------------

TF_EXPORT void tf_fake_hd_reset(void) {
  hdStopScheduler();
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.version = "3.4.0";
  f.callback_time_s = 50e-6;
  f.manual = false;
  f.rate_hz = 1000.0;
  for (std::size_t k = 0; k < kMaxDevices; ++k) {
    f.devices[k] = Dev{};
    f.devices[k].handle = static_cast<HHD>(k + 1);
  }
  f.device_count = 1;
  f.named = false;
  f.current = 0;
  f.selected = 0;
  f.error_count = 0;
  f.injections.clear();
  f.pending_overrun = 0;
  f.callback_count = 0;
  f.sync_count = 0;
  f.ticks = 0;
  f.sim_time_s = 0.0;
  f.violations = 0;
  f.last_violation = 0;
  f.last_violation_call[0] = '\0';
  f.errors_raised = 0;
  f.disable_device_calls = 0;
}

TF_EXPORT int tf_fake_hd_add_device(const char* name, const char* serial) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  if (f.running || name == nullptr || name[0] == '\0') return -1;
  for (std::size_t k = 0; k < f.device_count && f.named; ++k) {
    if (f.devices[k].initialized || f.devices[k].name == name) return -1;
  }
  std::size_t index = 0;
  if (f.named) {
    if (f.device_count == kMaxDevices) return -1;
    index = f.device_count++;
  } else if (f.devices[0].initialized) {
    return -1;
  }
  f.named = true;
  f.devices[index].name = name;
  f.devices[index].serial = serial != nullptr ? serial : "";
  return static_cast<int>(index);
}

TF_EXPORT int tf_fake_hd_select_device(const char* name) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  for (std::size_t k = 0; k < f.device_count; ++k) {
    if (name == nullptr || f.devices[k].name == name) {
      f.selected = k;
      return static_cast<int>(k);
    }
  }
  return -1;
}

TF_EXPORT void tf_fake_hd_set_manual(int on) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.manual = on != 0;
}

TF_EXPORT unsigned long tf_fake_hd_step(unsigned long ticks) {
  Fake& f = fake();
  std::unique_lock lock(f.mu);
  if (!f.running || !f.manual || ticks == 0) return 0;
  f.pending_steps += ticks;
  f.cv_step.notify_all();
  f.cv_done.wait(lock, [&] { return f.pending_steps == 0 || !f.running; });
  return f.running ? ticks : 0;
}

TF_EXPORT void tf_fake_hd_set_version(const char* version) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.version = version != nullptr ? version : "";
}

TF_EXPORT void tf_fake_hd_set_limits(double max_force_n, double max_continuous_force_n, double stiffness_n_per_mm,
                                     double damping_n_s_per_mm) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.max_force_n = max_force_n;
  d.max_continuous_force_n = max_continuous_force_n;
  d.stiffness_n_per_mm = stiffness_n_per_mm;
  d.damping_n_s_per_mm = damping_n_s_per_mm;
}

TF_EXPORT void tf_fake_hd_set_calibration(unsigned int state, int styles) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  // The reported position jumps by the uncalibrated offset when the state crosses OK: the
  // library's velocity filter starts afresh, as after hdUpdateCalibration.
  if ((state == HD_CALIBRATION_OK) != (d.calibration == HD_CALIBRATION_OK)) {
    d.have_reported = false;
    d.reported_velocity_mm = {};
  }
  d.calibration = state;
  d.calibration_styles = styles;
  d.sweeping = false;
}

TF_EXPORT void tf_fake_hd_set_calibration_update_error(unsigned int code) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.calibration_update_error = code;
}

TF_EXPORT void tf_fake_hd_set_model(const char* model) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.model = model != nullptr ? model : "";
}

TF_EXPORT void tf_fake_hd_set_inkwell(int stylus_in_inkwell) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.inkwell = stylus_in_inkwell != 0;
}

TF_EXPORT void tf_fake_hd_set_buttons(int buttons) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.buttons = buttons;
}

TF_EXPORT void tf_fake_hd_inject_error(unsigned int code, int internal, int where, unsigned long count) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.injections.push_back(Injection{f.selected, code, internal, where, count});
}

TF_EXPORT void tf_fake_hd_inject_overrun(unsigned int periods) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.pending_overrun = periods;
}

TF_EXPORT void tf_fake_hd_set_callback_time(double seconds) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  f.callback_time_s = seconds;
}

TF_EXPORT void tf_fake_hd_pin_hand(const double position_mm[3]) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.pinned = true;
  for (std::size_t i = 0; i < 3; ++i) d.hand_target[i] = position_mm[i] * 1e-3;
  if (!f.running) {
    d.position = d.hand_target;
    d.velocity = {};
  }
}

TF_EXPORT void tf_fake_hd_spring_hand(const double target_mm[3], double stiffness_n_per_m, double damping_n_s_per_m) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.pinned = false;
  for (std::size_t i = 0; i < 3; ++i) d.hand_target[i] = target_mm[i] * 1e-3;
  d.hand_k = stiffness_n_per_m;
  d.hand_b = damping_n_s_per_m;
}

TF_EXPORT void tf_fake_hd_set_motor_temperature(double t) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.temperature_override = t;
}

TF_EXPORT void tf_fake_hd_set_temperature_supported(int supported) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  d.temperature_supported = supported != 0;
}

TF_EXPORT void tf_fake_hd_get_stats(TfFakeHdStats* s) {
  Fake& f = fake();
  std::lock_guard lock(f.mu);
  Dev& d = f.selected_dev();
  *s = TfFakeHdStats{};
  s->ticks = f.ticks;
  s->sim_time_s = f.sim_time_s;
  s->frames = d.frames;
  for (std::size_t i = 0; i < 3; ++i) {
    s->last_force_n[i] = d.command[i];
    s->applied_force_n[i] = d.applied[i];
    s->position_mm[i] = d.position[i] * 1000.0;
    s->reported_position_mm[i] = d.reported_mm[i];
    s->joint_angles_rad[i] = d.joints[i];
  }
  s->max_force_norm_n = d.max_force_norm;
  s->force_output_enabled = d.force_output ? 1 : 0;
  s->enabled_uncalibrated_frames = d.enabled_uncalibrated;
  s->nonzero_uncalibrated_frames = d.nonzero_uncalibrated;
  s->protocol_violations = f.violations;
  s->last_violation = f.last_violation;
  std::memcpy(s->last_violation_call, f.last_violation_call, sizeof s->last_violation_call);
  s->errors_raised = f.errors_raised;
  s->async_callbacks = static_cast<int>(std::count_if(f.callbacks.begin(), f.callbacks.begin() + f.callback_count,
                                                      [](const Callback& c) { return c.active; }));
  s->scheduler_running = f.running ? 1 : 0;
  s->device_initialized = d.initialized ? 1 : 0;
  s->init_calls = d.init_calls;
  s->calibration_checks = d.calibration_checks;
  s->calibration_updates = d.calibration_updates;
  s->calibration_update_errors = d.calibration_update_errors;
  s->calibration_updates_in_frame = d.calibration_updates_in_frame;
  s->disable_device_calls = f.disable_device_calls;
  s->calibration = d.calibration;
  s->motor_temperature = motor_temperature(d);
  s->scheduler_rate_hz = f.rate_hz;
  s->handle = d.handle;
  s->device_count = static_cast<int>(f.device_count);
  const auto copy = [](char* out, std::size_t size, const std::string& in) {
    const std::size_t n = std::min(in.size(), size - 1);  // cut, never overrun
    std::memcpy(out, in.data(), n);
    out[n] = '\0';
  };
  copy(s->name, sizeof s->name, d.name);
  copy(s->serial, sizeof s->serial, d.serial);
}
// NOLINTEND(readability-identifier-naming)
