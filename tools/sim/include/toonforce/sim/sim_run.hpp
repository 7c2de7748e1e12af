// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce sim` (interfaces.md): a scene, a hand script and a simulated device in closed
/// loop for a given simulated duration; writes the trace and optionally a plot.

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/sim/closed_loop.hpp"
#include "toonforce/sim/sim_trace.hpp"
#include "toonforce/trace/telemetry_sink.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {

/// The longest simulation `sim` runs (one simulated day: 86.4 million ticks at 1 kHz).
inline constexpr double kMaxSimDurationS = 86400.0;

/// Where run_sim hands every trace row as numbers, besides the trace file or (with an empty
/// trace_path) instead of it: the Python module keeps them as arrays. Called from run_sim's
/// thread, once per row, in order.
class SimRowSink {
 public:
  virtual ~SimRowSink() = default;
  /// Before the first row: the columns after the core ten (sim_trace_columns) and the number of
  /// ticks to come (one more row if a stop ends the run early: the shut-down tick).
  virtual void begin(const std::vector<std::string>& extra_columns, std::int64_t ticks) = 0;
  virtual void row(const TraceRow& row) = 0;
};

struct SimOptions {
  std::string scene_path;
  /// Set: the scene is this TOML text, not the file's, and scene_path stands for it in messages
  /// (the Python module's scenes from a string or a dict, through the same loader and checks).
  std::optional<std::string> scene_text;
  bool allow_empty = false;  ///< a scene without effects is not an error (--allow-empty)
  bool strict = false;       ///< a plausibility warning refuses the start (--strict)
  std::uint64_t max_output_bytes = kDefaultTraceLimitBytes;  ///< the trace's size limit (0: none)
  std::string script_path;
  std::optional<std::string> script_text;  ///< set: the hand script is this text (as scene_text)
  std::optional<double> duration_s;        ///< default: the hand script's length
  std::string trace_path;                  ///< "-" writes to standard output; empty: no file (with `rows`)
  SimRowSink* rows = nullptr;              ///< also (or, without trace_path, only) every row as numbers
  /// Non-null: the warnings run_sim would print on standard error (the plausibility report's,
  /// the trace's room) go here instead, one message each, for a caller that shows them its own way.
  std::vector<std::string>* warnings = nullptr;
  std::string plot_path;  ///< empty: no plot; .png or .svg
  std::string plot_kind = "auto";
  std::string plot_title;
  host_sim::DevicePreset device = host_sim::DevicePreset::kFalcon;
  host_sim::Integrator integrator = host_sim::Integrator::kRk4;
  int substeps = 4;
  double rate_hz = 1000.0;
  std::uint64_t seed = 1;
  std::optional<double> sensor_noise_m;  ///< overrides the device preset's (0)
  ScalarKind scalar = ScalarKind::kDouble;
  std::optional<SineMethod> sine;  ///< overrides every impact's sine method
  /// Also sends every tick to this sink (the live viewer), from the simulation's thread.
  TelemetrySink* sink = nullptr;
  /// With a sink: simulated seconds per wall-clock second (1: real time, as a person would
  /// feel it; 0: as fast as the machine goes). The trace is the same either way.
  double pace = 1.0;
  /// Non-zero (a signal's number, set by a handler): the run stops after the tick under way,
  /// writes the loop's shut-down tick (zero force) as the trace's last row and reports.
  const std::atomic<int>* stop = nullptr;
};

struct SimSummary {
  std::string scene_name;
  std::string script_name;
  std::string device_name;
  std::int64_t ticks = 0;
  double duration_s = 0.0;
  double script_duration_s = 0.0;
  double peak_force_n = 0.0;
  double peak_force_t_s = 0.0;
  std::int64_t ticks_in_contact = 0;
  std::int64_t impacts = 0;
  std::int64_t cliff_falls = 0;
  std::int64_t rate_limited = 0;
  std::int64_t clamped = 0;
  std::int64_t fault_ticks = 0;
  std::uint32_t fault_bits = 0;
  Vec3<double> final_position_m;
  double device_work_j = 0.0;
  std::vector<double> last_cliff_states;     ///< to count SUPPORTED -> FALLEN transitions
  std::int64_t ticks_outside_workspace = 0;  ///< the handle beyond the device's workspace
  std::int64_t engaging_ticks = 0;           ///< the loop waited for the scene force to fall below engage_force
  std::int64_t soft_start_ticks = 0;
  std::int64_t passivity_ticks = 0;  ///< the passivity controller damped
  std::uint32_t last_state = 0;      ///< LoopState at the end
  std::string trace_error;           ///< non-empty: the trace could not be written (the run went on)
  int stop_signal = 0;               ///< the signal that stopped the run before its end (0: none)
};

/// Accumulates the summary from records (shared by the CLI, the figures and the benchmark).
void add_to_summary(SimSummary& summary, const SimRecord& record, const SummaryColumns& columns);

/// The configuration the options ask for (device preset, noise, integrator, rate).
SimConfig sim_config(const SimOptions& options);

Result<SimSummary> run_sim(const SimOptions& options);
std::string format_sim_summary(const SimSummary& summary, const SimOptions& options);

}  // namespace toonforce
