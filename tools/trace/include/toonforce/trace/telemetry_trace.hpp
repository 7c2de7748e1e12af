#pragma once
/// The servo loop's telemetry frame (control/telemetry.hpp) as trace rows: the ten core columns,
/// then the safety layer's view of the tick and its timing.

#include <array>
#include <string>
#include <vector>

#include "toonforce/control/telemetry.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce {

/// Extra columns after the core ten, in order:
///   scene_fx,scene_fy,scene_fz  the scene's force before the safety layer [N]
///   damping_fx,damping_fy,damping_fz  the passivity controller's damping [N]
///   faults,latched,limits,state  Fault bits, latched Fault bits, Limit bits, LoopState
///   contact,impact_t,cliff_state  the effects' diagnostics (impact_t NaN when none runs)
///   max_force,temperature,observed_energy,episode_energy,gain  clamp in force [N], thermal
///       theta (1 = rated), Hannaford-Ryu E_obs [J], largest active episode energy [J], soft start
///   tick,wake_latency_us,compute_us,slack_us,missed  integer time and the runner's timing
std::vector<std::string> telemetry_columns();
inline constexpr std::size_t kTelemetryExtraColumns = 23;

/// Writes one frame as a trace row.
bool write_frame(TraceWriter& writer, const TelemetryFrame& frame);

}  // namespace toonforce
