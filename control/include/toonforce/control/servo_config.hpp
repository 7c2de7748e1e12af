#pragma once
/// Settings of the servo loop's safety layer (spec effects.md §6 "The servo loop adds more"),
/// in double as a scene file or a program gives them; the loop converts them once. Defaults
/// are the documented ones (docs/spec/interfaces.md, [device] keys marked as toonforce
/// extensions). `with_device` fills what the scene leaves open from the device's nominal
/// figures; `check_servo_config` says what is wrong with a configuration before anything runs.

#include <cstdint>
#include <string>

#include "toonforce/control/controller.hpp"
#include "toonforce/control/passivity.hpp"
#include "toonforce/control/thermal_model.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

struct SafetyConfig {
  /// [N] forces engage (after enable, start and re-arm) only once the scene force at the
  /// current position is below this, so enabling inside a wall never throws the handle
  /// (CHAI3D's 0.2 N start-up rule).
  double engage_force_n = 0.2;
  /// [s] linear soft-start ramp from 0 to full force, after engaging and after every fault; 0: none.
  double soft_start_s = 1.0;
  /// [m/s] above this HIP speed the force is off (OpenHaptics-style software velocity limit).
  bool has_max_velocity = true;
  double max_velocity_m_per_s = 1.2;
  /// [m] outside this box (scene frame) the force is off; from the device unless set.
  bool has_workspace = false;
  Vec3<double> workspace_min_m;
  Vec3<double> workspace_max_m;
  /// A gap of more than this many periods between two ticks (missed deadlines, a stalled
  /// loop) latches Fault::kWatchdog. The heartbeat watchdog outside the loop uses it too.
  std::int64_t watchdog_periods = 30;
  /// This many failed device exchanges in a row latch Fault::kDeviceSilent.
  std::int64_t device_timeout_periods = 10;
  ThermalConfig thermal;
  PassivityConfig passivity;
};

struct ServoConfig {
  ControllerConfig controller;  ///< limits, velocity cut-off; period_s > 0 (the servo period)
  SafetyConfig safety;
};

/// The configuration for a device: the clamp becomes the smaller of the configured and the
/// device's nominal maximum force (spec §6), and the device's workspace and continuous force
/// fill the workspace bounds and the thermal model when the configuration leaves them unset.
ServoConfig with_device(ServoConfig config, const DeviceInfo& device);

/// Empty when `config` is usable by a ServoLoop, else one problem per line.
std::string check_servo_config(const ServoConfig& config);

}  // namespace toonforce
