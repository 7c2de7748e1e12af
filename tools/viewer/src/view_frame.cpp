// SPDX-License-Identifier: Apache-2.0
#include "toonforce/viewer/view_frame.hpp"

#include <limits>

namespace toonforce::viewer {

std::vector<std::string> view_columns(const std::vector<std::string>& effect_values) {
  std::vector<std::string> columns(kViewColumns.begin(), kViewColumns.end());
  for (std::size_t i = 0; i < kViewEffectValues; ++i)
    columns.push_back(i < effect_values.size() ? effect_values[i] : "");
  return columns;
}

ViewFrame view_frame(const TelemetryFrame& f, bool has_timing) noexcept {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const auto ns_to_us = [has_timing](std::int64_t ns) { return has_timing ? static_cast<double>(ns) * 1e-3 : kNaN; };
  ViewFrame v;
  v.fill(kNaN);
  v[kT] = f.t_s;
  v[kTick] = static_cast<double>(f.tick);
  v[kX] = f.position_m.x;
  v[kY] = f.position_m.y;
  v[kZ] = f.position_m.z;
  v[kVx] = f.velocity_m_per_s.x;
  v[kVy] = f.velocity_m_per_s.y;
  v[kVz] = f.velocity_m_per_s.z;
  v[kFx] = f.force_n.x;
  v[kFy] = f.force_n.y;
  v[kFz] = f.force_n.z;
  v[kSceneFx] = f.scene_force_n.x;
  v[kSceneFy] = f.scene_force_n.y;
  v[kSceneFz] = f.scene_force_n.z;
  v[kFaults] = static_cast<double>(f.faults);
  v[kLatched] = static_cast<double>(f.latched);
  v[kLimits] = static_cast<double>(f.limits);
  v[kState] = static_cast<double>(f.state);
  v[kContact] = f.in_contact ? 1.0 : 0.0;
  v[kMaxForce] = f.max_force_n;
  v[kGain] = f.gain;
  v[kWakeLatencyUs] = ns_to_us(f.timing.wake_latency_ns);
  v[kComputeUs] = ns_to_us(f.timing.compute_ns);
  v[kSlackUs] = ns_to_us(f.timing.slack_ns);
  v[kMissed] = has_timing ? static_cast<double>(f.timing.missed_total) : kNaN;
  for (std::size_t i = 0; i < kViewEffectValues && i < f.value_count; ++i) v[kFirstEffectValue + i] = f.values[i];
  return v;
}

}  // namespace toonforce::viewer
