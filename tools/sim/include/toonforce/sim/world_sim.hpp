// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce sim` of a world scene (config/world_file.hpp): every device of the world
/// simulated, each with its own hand script, ticked together by control/world.hpp in simulated
/// time, deterministically. The trace has one row a tick and, per device, its HIP in the world
/// frame, the force its loop commanded (in its own frame), the forces between HIPs on it (the
/// couplings' and the ball's, world frame, before its safety chain), its faults and state.

#include <atomic>
#include <map>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/integrator.hpp"
#include "toonforce/sim/world_trace.hpp"

namespace toonforce {

/// Where run_world_sim hands every trace row as numbers, besides the trace file or (with an empty
/// trace_path) instead of it: the Python module keeps them as arrays. From run_world_sim's thread.
class WorldRowSink {
 public:
  virtual ~WorldRowSink() = default;
  /// Before the first row: every column's name (the trace's header) and the ticks to come.
  virtual void begin(const std::vector<std::string>& columns, std::int64_t ticks) = 0;
  virtual void row(const std::vector<double>& values) = 0;
};

struct WorldSimOptions {
  std::string scene_path;
  std::optional<std::string> scene_text;  ///< set: the world is this text; scene_path names it in messages
  /// One hand script per device: (device name, hand script file).
  std::vector<std::pair<std::string, std::string>> scripts;
  /// Hand scripts given as text, by device name (their entry in `scripts` names them in messages).
  std::map<std::string, std::string> script_texts;
  std::optional<double> duration_s;  ///< default: the longest hand script
  std::string trace_path;            ///< "-": standard output; empty: no file (with `rows`)
  WorldRowSink* rows = nullptr;      ///< also (or, without trace_path, only) every row as numbers
  /// Devices whose backend is "sim" are simulated as this class; "falcon" and "omni" devices as theirs.
  host_sim::DevicePreset device = host_sim::DevicePreset::kFalcon;
  host_sim::Integrator integrator = host_sim::Integrator::kRk4;
  int substeps = 4;
  double rate_hz = 1000.0;
  std::uint64_t seed = 1;
  /// A device whose cable is pulled at a time: from then on its reads and writes fail (it gets
  /// no force; its hand and handle go on moving). (name, seconds)
  std::optional<std::pair<std::string, double>> fail;
  /// Non-zero (a signal's number): stop after the tick under way, write the shut-down tick.
  const std::atomic<int>* stop = nullptr;
};

struct WorldSimDeviceSummary {
  std::string name;
  std::string script;
  double peak_force_n = 0.0;
  std::int64_t fault_ticks = 0;
  std::uint32_t latched = 0;  ///< at the end
  std::uint8_t state = 0;     ///< LoopState at the end
  Vec3<double> final_hip_m;   ///< world frame
};

struct WorldSimSummary {
  std::string scene_name;
  std::int64_t ticks = 0;
  double duration_s = 0.0;
  std::vector<WorldSimDeviceSummary> devices;
  std::optional<double> held_at_s;  ///< when one stop first held every device
  std::string held_by;              ///< the device whose fault started it
  /// The largest |force on a + force on b| of any coupling over the run [N] (Newton: 0).
  double coupling_imbalance_n = 0.0;
  /// Ticks after the hold began on which some device was still commanded a force.
  std::int64_t forced_while_held = 0;
  std::optional<Vec3<double>> final_ball_m;
  int stop_signal = 0;
};

/// A world's device as `sim` simulates it: its backend's model (a "sim" device: `for_sim`'s),
/// and its loop's configuration, its own [device] keys completed by that model's figures.
/// `check` takes the same, so that it checks what `sim` runs.
struct SimulatedWorldDevice {
  host_sim::DeviceParams params;
  ServoConfig config;
};
SimulatedWorldDevice simulated_device(const WorldDeviceEntry& device, host_sim::DevicePreset for_sim, double period_s);

Result<WorldSimSummary> run_world_sim(const WorldSimOptions& options);
std::string format_world_sim_summary(const WorldSimSummary& summary, const WorldSimOptions& options);

/// Parses `--script NAME=FILE` into (name, file); an error names the form expected.
Result<std::pair<std::string, std::string>> parse_named_script(const std::string& text);

}  // namespace toonforce
