#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {

std::vector<std::string> telemetry_columns() {
  return {"scene_fx",   "scene_fy",        "scene_fz",       "damping_fx", "damping_fy",
          "damping_fz", "faults",          "latched",        "limits",     "state",
          "contact",    "impact_t",        "cliff_state",    "max_force",  "temperature",
          "observed_energy", "episode_energy", "gain",       "tick",       "wake_latency_us",
          "compute_us", "slack_us",        "missed"};
}

bool write_frame(TraceWriter& writer, const TelemetryFrame& f) {
  const std::array<double, kTelemetryExtraColumns> extras{
      f.scene_force_n.x,
      f.scene_force_n.y,
      f.scene_force_n.z,
      f.damping_n.x,
      f.damping_n.y,
      f.damping_n.z,
      static_cast<double>(f.faults),
      static_cast<double>(f.latched),
      static_cast<double>(f.limits),
      static_cast<double>(f.state),
      f.in_contact ? 1.0 : 0.0,
      f.impact_time_s,
      static_cast<double>(f.cliff_state),
      f.max_force_n,
      f.temperature,
      f.observed_energy_j,
      f.episode_energy_j,
      f.gain,
      static_cast<double>(f.tick),
      static_cast<double>(f.timing.wake_latency_ns) / 1000.0,
      static_cast<double>(f.timing.compute_ns) / 1000.0,
      static_cast<double>(f.timing.slack_ns) / 1000.0,
      static_cast<double>(f.timing.missed_total)};
  return writer.write({f.t_s, f.position_m, f.velocity_m_per_s, f.force_n}, extras);
}

}  // namespace toonforce
