// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce run` of a world scene (`[[device]]` tables, config/world_file.hpp): every device
/// of the world opened, each with its own loop and safety chain, ticked together in real time
/// by control/world_session.hpp; one trace row a tick with every device's values named by the
/// device (sim/world_trace.hpp), and a summary per device. `--device sim` simulates every device
/// (one hand script per device, `--script NAME=FILE`); `--device scene` opens each device as
/// its table says (`backend`, `select`).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/run/run.hpp"

namespace toonforce {

struct WorldRunDevice {
  std::string name;
  std::string backend;      ///< as opened: "sim", "falcon"
  std::string device_name;  ///< the driver's: "Novint Falcon (serial ...)", "simulated falcon ..."
  std::string script;       ///< its hand script (simulated devices), or ""
  double peak_force_n = 0.0;
  std::int64_t fault_ticks = 0;
  std::uint32_t fault_bits = 0;  ///< union over the run
  std::uint32_t latched_at_end = 0;
  std::int64_t device_limited_ticks = 0;
  /// A device on a clock of its own (the Omni), bridged to the world's (control/clock_bridge.hpp):
  /// how old each reading was when the world used it, how old each force when the device
  /// applied it [ns], and the device ticks that wrote zero for a force too old.
  bool bridged = false;
  LatencySummary reading_age;
  LatencySummary force_age;
  std::int64_t stale_force_ticks = 0;
};

struct WorldRunSummary {
  RunReport report;
  std::string scene_name;
  std::vector<WorldRunDevice> devices;
  std::size_t couplings = 0;
  bool has_ball = false;
  std::uint64_t frames_written = 0;
  std::uint64_t frames_dropped = 0;
  /// The largest |sum over every device of the couplings' forces on it| of any frame [N] (0 by
  /// Newton's third law).
  double coupling_imbalance_n = 0.0;
  std::optional<double> held_at_s;     ///< when one stop first held every device
  std::string held_by;                 ///< the device whose fault started it
  std::int64_t forced_while_held = 0;  ///< frames after the hold began with any device's force not zero
  std::int64_t rearms = 0;
  bool live = false;                  ///< the world took scene updates (--control)
  std::uint64_t updates_applied = 0;  ///< live: updates every device applied (on one tick each)
  std::uint64_t updates_refused = 0;  ///< live: updates the world refused (a part failed its checks)
  std::string trace_error;
};

/// Runs the world scene options.scene_path (options.device "sim" or "scene"); errors come back
/// before the first tick.
Result<WorldRunSummary> run_world_servo(const RunOptions& options);
std::string format_world_run_summary(const WorldRunSummary& summary, const RunOptions& options);
std::string world_stats_json(const WorldRunSummary& summary, const RunOptions& options);

}  // namespace toonforce
