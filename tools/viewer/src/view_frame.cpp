#include "toonforce/viewer/view_frame.hpp"

#include <limits>

namespace toonforce::viewer {

ViewFrame view_frame(const TelemetryFrame& f, bool has_loop) noexcept {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const auto ns_to_us = [has_loop](std::int64_t ns) { return has_loop ? static_cast<double>(ns) * 1e-3 : kNaN; };
  ViewFrame v;
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
  v[kState] = has_loop ? static_cast<double>(f.state) : kNaN;
  v[kContact] = f.in_contact ? 1.0 : 0.0;
  v[kImpactT] = f.impact_time_s;
  v[kCliffState] = static_cast<double>(f.cliff_state);
  v[kMaxForce] = f.max_force_n;
  v[kGain] = has_loop ? f.gain : kNaN;
  v[kWakeLatencyUs] = ns_to_us(f.timing.wake_latency_ns);
  v[kComputeUs] = ns_to_us(f.timing.compute_ns);
  v[kSlackUs] = ns_to_us(f.timing.slack_ns);
  v[kMissed] = has_loop ? static_cast<double>(f.timing.missed_total) : kNaN;
  return v;
}

}  // namespace toonforce::viewer
