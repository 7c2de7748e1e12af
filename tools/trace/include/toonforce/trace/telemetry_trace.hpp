// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The servo loop's telemetry frame (control/telemetry.hpp) as trace rows, the same for
/// `toonforce run` and `toonforce sim`: the ten core columns, then the safety layer's view of the
/// tick, then what the scene's effects show (one column per value, named after the effect:
/// "surface1.impact_t", "cliff1.state"), then, in `run`, the runner's timing.

#include <array>
#include <span>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "toonforce/control/telemetry.hpp"
#include "toonforce/effects/scene.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce {

/// The columns after the core ten:
///   scene_fx,scene_fy,scene_fz        the scene's force before the safety layer [N]
///   damping_fx,damping_fy,damping_fz  the passivity controller's damping [N]
///   faults,latched,limits,state       Fault bits, latched Fault bits, Limit bits, LoopState
///   contact                           the HIP touches some effect (0/1)
///   max_force,temperature,observed_energy,episode_energy,gain  clamp in force [N], thermal
///       theta (1 = rated), Hannaford-Ryu E_obs [J], largest active episode energy [J], soft start
///   tick                              integer time
///   EFFECT VALUES                     `effect_values`, e.g. surface1.contact,surface1.impact_t
///   wake_latency_us,compute_us,slack_us,missed   the runner's timing (`with_timing`)
std::vector<std::string> telemetry_columns(const std::vector<std::string>& effect_values, bool with_timing);
/// How many values write_frame() writes after the core ten.
std::size_t telemetry_extra_count(std::size_t effect_values, bool with_timing);

/// The most values a trace row has after the core ten: the loop's, the effects', the timing's,
/// and up to 64 of a producer's own.
inline constexpr std::size_t kMaxTraceRowValues = 17 + kMaxEffectValues + 4 + 64;

/// One trace row as numbers, before any text: what write_frame() hands the TraceWriter, and
/// what a caller that keeps rows as numbers (the Python module's arrays) takes instead, so both
/// hold the same doubles.
struct TraceRow {
  TraceCore core;
  std::array<double, kMaxTraceRowValues> values{};  ///< the columns after the core ten
  std::size_t count = 0;                            ///< how many of `values` are used
  std::span<const double> extras() const noexcept { return {values.data(), count}; }
};

/// Fills `row` with one frame's numbers, in the order of telemetry_columns(), then `more`;
/// false (and `row` unusable) if `more` does not fit.
bool frame_row(TraceRow& row, const TelemetryFrame& frame, std::size_t effect_values, bool with_timing,
               std::span<const double> more = {});

/// Writes one frame as a trace row: telemetry_columns(), then `more` (a producer's own columns).
bool write_frame(TraceWriter& writer, const TelemetryFrame& frame, std::size_t effect_values, bool with_timing,
                 std::span<const double> more = {});

/// Which of a scene's values the run summaries count (the library's effects): running impacts'
/// times and cliffs' states, by their names.
struct SummaryColumns {
  std::vector<std::size_t> impact_times;  ///< "*.impact_t": 0 on the tick a transient triggers
  std::vector<std::size_t> cliff_states;  ///< "cliff*.state": 0 supported, 1 fallen
  static SummaryColumns of(const std::vector<std::string>& value_names);
};

/// The names of a scene's effect values, in the order the servo loop reports them:
/// KEY + NUMBER + "." + VALUE ("surface1.impact_t", "cliff2.state").
template <SceneType SceneT>
std::vector<std::string> effect_value_names(const SceneT& scene) {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < scene.effect_count(); ++i) {
    const EffectInfo info = scene.effect_info(i);
    for (const ValueInfo& v : info.values) names.push_back(fmt::format("{}{}.{}", info.key, info.number, v.name));
  }
  return names;
}

}  // namespace toonforce
