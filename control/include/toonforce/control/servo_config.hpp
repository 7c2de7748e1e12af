// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Settings of the servo loop (spec effects.md §6 "The servo loop adds more"), in double as a
/// scene file or a program gives them; the loop converts them once. Defaults are the documented
/// ones (docs/spec/interfaces.md, [device] keys marked as toonforce extensions). `with_device`
/// fills what the scene leaves open from the device's nominal figures; `check_servo_config` says
/// what is wrong with a configuration before anything runs.
///
/// Which stages a loop has at all is a compile-time choice (LoopStages): `toonforce run`, `sim`
/// and the tests have every stage; `replay` has only those of effects.md §6 (non-finite guard,
/// rate limit, clamp), so a replayed force is the spec's, and a stage no configuration of that
/// loop can turn on costs nothing.

#include <cstdint>
#include <string>

#include "toonforce/control/engage.hpp"
#include "toonforce/control/force_safety.hpp"
#include "toonforce/control/motion_limits.hpp"
#include "toonforce/control/passivity.hpp"
#include "toonforce/control/supervisor.hpp"
#include "toonforce/control/thermal_model.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

/// The stages a servo loop is built with (a template argument of ServoLoop).
struct LoopStages {
  bool supervisor = true;     ///< latches, watchdog, e-stop, enable, homing, device silence
  bool engage = true;         ///< engage below engage_force, then the soft start
  bool passivity = true;      ///< observer, and the controller for the active effects' budgets
  bool thermal = true;        ///< the motor thermal model derating the clamp
  bool motion_limits = true;  ///< velocity limit and workspace bounds
  bool live = false;          ///< takes scene updates between ticks (scene_updates.hpp)
  /// May take dt from time stamps (ServoConfig::time_from_stamps: replay). A loop without it
  /// runs on its fixed period only, and computes what depends on dt from the tick count with
  /// 32-bit divisions at most (its worst case has no 64-bit one).
  bool stamps = false;
};
/// Every stage: a loop that drives a device (run, sim, the examples).
inline constexpr LoopStages kEveryStage{};
/// Only effects.md §6 (non-finite guard, force-rate limit, clamp), time from stamps or a period: replay.
inline constexpr LoopStages kSpecStages{false, false, false, false, false, false, true};
/// Every stage, and a scene an application changes while the loop runs.
inline constexpr LoopStages kLiveStages{true, true, true, true, true, true};

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
  /// [s] a live scene's update keeps the force continuous and fades the difference out over
  /// this time (docs/spec/live-scenes.md); 0: none (an update is felt as a step).
  double update_fade_s = 0.25;
  /// A gap of more than this many periods between two ticks (missed deadlines, a stalled
  /// loop) latches Fault::kWatchdog. The heartbeat watchdog outside the loop uses it too.
  std::int64_t watchdog_periods = 30;
  /// This many failed device exchanges in a row latch Fault::kDeviceSilent.
  std::int64_t device_timeout_periods = 10;
  ThermalConfig thermal;
  PassivityConfig passivity;
};

struct ServoConfig {
  /// [s] > 0: the servo period (ticks are integer multiples of it). With `time_from_stamps`,
  /// the first tick's dt; every later dt is the difference of the ticks' stamps (replay). Only a
  /// loop built with LoopStages::stamps (kSpecStages) reads stamps; every other runs on its period.
  double period_s = 0.0;
  bool time_from_stamps = false;
  ForceLimits limits;  ///< the clamp and the force-rate limit (effects.md §6)
  double velocity_cutoff_hz = VelocityEstimator<double>::kDefaultCutoffHz;
  SafetyConfig safety;

  constexpr SupervisorConfig supervisor() const noexcept {
    return {safety.watchdog_periods, safety.device_timeout_periods};
  }
  constexpr EngageConfig engage() const noexcept { return {safety.engage_force_n, safety.soft_start_s, period_s}; }
  constexpr MotionLimitsConfig motion_limits() const noexcept {
    return {safety.has_max_velocity, safety.max_velocity_m_per_s, safety.has_workspace, safety.workspace_min_m,
            safety.workspace_max_m};
  }
};

/// The configuration for a device: the clamp becomes the smaller of the configured and the
/// device's nominal maximum force (spec §6), and the device's workspace and continuous force
/// fill the workspace bounds and the thermal model when the configuration leaves them unset.
ServoConfig with_device(ServoConfig config, const DeviceInfo& device);

/// Empty when `config` is usable by a ServoLoop, else one problem per line.
std::string check_servo_config(const ServoConfig& config);

}  // namespace toonforce
