// SPDX-License-Identifier: Apache-2.0
#include "toonforce/control/servo_config.hpp"

#include <algorithm>
#include <cmath>

namespace toonforce {

ServoConfig with_device(ServoConfig config, const DeviceInfo& device) {
  ForceLimits& limits = config.limits;
  if (device.max_force_n > 0.0) {
    limits.max_force_n = limits.has_max_force ? std::min(limits.max_force_n, device.max_force_n) : device.max_force_n;
    limits.has_max_force = true;
  }
  SafetyConfig& safety = config.safety;
  const Vec3<double>& lo = device.workspace_min_m;
  const Vec3<double>& hi = device.workspace_max_m;
  if (!safety.has_workspace && lo.x < hi.x && lo.y < hi.y && lo.z < hi.z) {
    safety.has_workspace = true;
    safety.workspace_min_m = lo;
    safety.workspace_max_m = hi;
  }
  if (safety.thermal.continuous_force_n <= 0.0 && device.max_continuous_force_n > 0.0) {
    safety.thermal.continuous_force_n = device.max_continuous_force_n;
  }
  return config;
}

std::string check_servo_config(const ServoConfig& config) {
  std::string problems;
  const auto problem = [&problems](const char* text) {
    problems += text;
    problems += '\n';
  };
  const auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!finite_positive(config.period_s)) problem("the servo period must be > 0");
  if (!finite_positive(config.velocity_cutoff_hz)) problem("velocity_cutoff must be > 0");
  const ForceLimits& limits = config.limits;
  if (limits.has_max_force && !finite_positive(limits.max_force_n)) problem("max_force must be > 0");
  if (limits.has_max_force_rate && !finite_positive(limits.max_force_rate_n_per_s))
    problem("max_force_rate must be > 0");
  const SafetyConfig& s = config.safety;
  if (!(std::isfinite(s.engage_force_n) && s.engage_force_n > 0.0)) problem("engage_force must be > 0");
  if (!(std::isfinite(s.soft_start_s) && s.soft_start_s >= 0.0)) problem("soft_start must be >= 0");
  if (s.has_max_velocity && !finite_positive(s.max_velocity_m_per_s)) problem("max_velocity must be > 0");
  if (s.has_workspace && !(s.workspace_min_m.x < s.workspace_max_m.x && s.workspace_min_m.y < s.workspace_max_m.y &&
                           s.workspace_min_m.z < s.workspace_max_m.z)) {
    problem("workspace_min must be below workspace_max on every axis");
  }
  if (s.watchdog_periods < 1) problem("watchdog_periods must be >= 1");
  if (s.device_timeout_periods < 1) problem("device_timeout_periods must be >= 1");
  if (s.thermal.enabled()) {
    if (!std::isfinite(s.thermal.continuous_force_n)) problem("continuous_force must be finite");
    if (!finite_positive(s.thermal.time_constant_s)) problem("thermal_time_constant must be > 0");
    if (!(s.thermal.derate_start >= 0.0 && s.thermal.derate_start < 1.0))
      problem("thermal_derate_start must be in [0, 1)");
    if (!limits.has_max_force) problem("the thermal model needs a max_force (from the scene or the device)");
  }
  if (!finite_positive(s.passivity.budget_j)) problem("passivity_budget must be > 0");
  if (!finite_positive(s.passivity.max_damping_n_s_per_m)) problem("passivity_max_damping must be > 0");
  return problems;
}

}  // namespace toonforce
