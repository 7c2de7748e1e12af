// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce run`: the servo loop on a device in real time (spec interfaces.md), as a library
/// so tests drive it without a process. The command line's part only: which device and files,
/// the scene's and the device's limits merged, the summary. The loop runs as a servo session
/// (control/servo_session.hpp) on the device's own clock, whichever backend it is.

#include <concepts>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/control/faults.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/scene_updates.hpp"
#include "toonforce/control/servo_session.hpp"
#include "toonforce/control/world_updates.hpp"
#include "toonforce/math/scalar_kind.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/trace/telemetry_sink.hpp"
#include "toonforce/trace/trace_writer.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/gpio/line_spec.hpp"
#include "toonforce/hal/omni/omni_device.hpp"

namespace toonforce {
class WorldRowSink;  // sim/world_sim.hpp
namespace guardian {
struct SharedPage;
}  // namespace guardian

/// Live scenes (`--control`): the mailbox the run's loop takes scene updates from,
/// for the run's scalar type (the others stay null). The application's side (the control
/// protocol's SceneEditor) pushes into it; it outlives the run.
struct LiveMailboxes {
  SceneMailbox<RuntimeScene<double>>* of_double = nullptr;
  SceneMailbox<RuntimeScene<float>>* of_float = nullptr;
  SceneMailbox<RuntimeScene<Q16_16>>* of_q16 = nullptr;
  /// A world's (`run --scene WORLD --control`): one update for all its devices (world_updates.hpp).
  WorldMailbox<RuntimeScene<double>>* of_world = nullptr;
  template <Scalar S>
  SceneMailbox<RuntimeScene<S>>* of() const noexcept {
    if constexpr (std::same_as<S, double>) {
      return of_double;
    } else if constexpr (std::same_as<S, float>) {
      return of_float;
    } else {
      return of_q16;
    }
  }
};

/// The longest `--duration` (30 days; 0 runs until stopped).
inline constexpr double kMaxRunDurationS = 30.0 * 86400.0;

struct RunOptions {
  std::string device;        ///< sim | falcon | omni; a world scene: sim | scene (world_run.hpp)
  bool allow_empty = false;  ///< a scene without effects is not an error (--allow-empty)
  bool strict = false;       ///< a plausibility warning refuses the start (--strict)
  std::uint64_t max_output_bytes = kDefaultTraceLimitBytes;  ///< the trace's size limit (0: none)
  /// --device sim: the simulated hand follows this script (docs/HAND_SCRIPTS.md) and then holds
  /// its last point; empty: it holds still 1 cm above the workspace centre.
  std::string hand_script_path;
  std::string sim_device = "falcon";  ///< --device sim: the device model's preset (falcon | omni)
  /// A world scene: one hand script per simulated device, (device name, file); a device
  /// without one holds still 1 cm above its workspace centre.
  std::vector<std::pair<std::string, std::string>> world_scripts;
  /// Hand scripts given as text, by device name (their entry in `world_scripts` names them).
  std::map<std::string, std::string> world_script_texts;
  /// A world scene: also every trace row as numbers, from the writer thread (the Python module).
  WorldRowSink* world_rows = nullptr;
  /// A world scene: pull this simulated device's cable after this many seconds (its reads and
  /// writes fail from then on), to see one stop hold every device.
  std::optional<std::pair<std::string, double>> world_fail;
  std::uint64_t seed = 1;  ///< --device sim: sensor-noise seed
  FalconOptions falcon;    ///< --device falcon: which Falcon, firmware to load
  OmniOptions omni;        ///< --device omni: which device, where libHD is
  gpio::GpioOptions gpio;  ///< tick pin, e-stop, enable, lights (none: no GPIO code runs)
  std::string scene_path;
  /// Set: the scene is this TOML text, not the file's; scene_path names it in messages (the
  /// Python module's runs of a scene given as a string or a dict).
  std::optional<std::string> scene_text;
  double rate_hz = 1000.0;      ///< 500 .. 10000
  double duration_s = 0.0;      ///< 0: until SIGINT/SIGTERM (or 'q' on a terminal)
  std::string trace_path;       ///< empty: no trace
  std::string stats_json_path;  ///< empty: none
  int cpu = -1;
  int priority = 80;
  bool allow_non_realtime = false;
  bool lock_memory = true;
  ScalarKind scalar = default_run_scalar();
  bool handle_signals = true;    ///< install the SIGINT/SIGTERM/fatal-signal handlers
  bool interactive = true;       ///< read 'r' (re-arm) and 'q' (stop) from stdin if it is a terminal
  std::FILE* messages = stderr;  ///< fault messages during the run
  /// Also sends every frame to this sink (the live viewer), from the writer thread that
  /// consumes the telemetry ring: the servo thread does no work for it.
  TelemetrySink* sink = nullptr;
  /// Live scenes: the loop takes scene updates from here (null: a loop without the live stage).
  const LiveMailboxes* live = nullptr;
  /// The page shared with `toonforce run`'s guardian process (guardian.hpp), when there is one:
  /// the loop's heartbeat, the device's external zero, the frames the writer takes.
  guardian::SharedPage* guardian = nullptr;
  /// The command's stop flag before the loop (command_stop.hpp): a stop signal that came while
  /// the device opened stops the loop before its first tick (zero force, the summary).
  const std::atomic<int>* early_stop = nullptr;

  /// q16.16 in a firmware build (TOONFORCE_FIRMWARE=ON), else double.
  static ScalarKind default_run_scalar() noexcept;
};

/// What a run did.
struct RunSummary {
  RunReport report;
  std::string scene_name;
  std::size_t surfaces = 0;
  std::size_t cliffs = 0;
  std::string device_name;
  std::uint64_t frames_written = 0;
  std::uint64_t frames_dropped = 0;  ///< telemetry ring full: frames not written
  std::int64_t fault_ticks = 0;      ///< frames with any fault bit
  std::uint32_t fault_bits = 0;      ///< union over the run
  std::uint32_t latched_at_end = 0;
  std::int64_t rearms = 0;  ///< latched faults cleared during the run
  std::string trace_error;  ///< non-empty: the trace could not be written (the run went on)
  double peak_force_n = 0.0;
  /// Ticks whose reading said the force written before was more than the device could give
  /// (Limit::kDeviceLimited): the user felt less than the scene asked.
  std::int64_t device_limited_ticks = 0;
  bool live = false;                  ///< the loop took scene updates (--control)
  std::uint64_t updates_applied = 0;  ///< live: scene updates the loop applied
  std::uint64_t updates_refused = 0;  ///< live: updates the loop refused (failed its checks)
};

/// Opens the device backend `options.device` names, for a loop at `options.rate_hz`.
Result<std::unique_ptr<DeviceDriver>> open_device(const RunOptions& options);

/// Why the rate or the duration cannot be run ("" if they can).
std::string run_options_problem(const RunOptions& options);

/// Runs; errors (bad scene, no device, real time refused) come back before the first tick.
Result<RunSummary> run_servo(const RunOptions& options);

std::string format_run_summary(const RunSummary& summary, const RunOptions& options);
std::string stats_json(const RunSummary& summary, const RunOptions& options);
/// The session's options for a run of `options` (its rate, duration, scheduling, guardian,
/// signals), with the heartbeat watchdog at `watchdog_periods`. One device's run and a world's.
SessionOptions session_options(const RunOptions& options, std::int64_t watchdog_periods);
/// After the session: tells the guardian the loop ended (again, for a run that never ticked), and
/// says so if the guardian itself ended during the run.
void after_session(const RunOptions& options);
/// The summary's trace line: its rows and dropped frames, or why it is incomplete.
std::string format_run_trace(const std::string& trace_path, const std::string& trace_error,
                             std::uint64_t frames_written, std::uint64_t frames_dropped);
/// The summary's real-time, run and timing lines.
std::string format_run_timing(const RunReport& report, double rate_hz);
/// A latency summary as JSON, in microseconds.
std::string json_latency(const LatencySummary& summary);
/// "watchdog (missed ticks), emergency stop" (empty for none).
std::string describe_faults(std::uint32_t bits);

}  // namespace toonforce
