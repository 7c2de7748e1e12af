// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The closed loop of `toonforce sim` and `toonforce figures`: the servo loop (control/
/// servo_loop.hpp, every stage, as `toonforce run` has it) on the simulated device and hand, in
/// simulated time, as fast as the machine goes, deterministically. Each tick:
///   simulated device reading (delayed, quantised) -> ServoLoop (supervisor, velocity, scene,
///   safety chain) -> force written (saturated, DAC-quantised, held over the tick) -> device
///   and hand advanced over the tick.
/// The loop's configuration is the one `run --device sim` uses: the scene's, completed by the
/// simulated device's figures (with_device), so a scene previewed here behaves as on the device.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce {

/// How to simulate: the device, the integration, the loop's scalar.
struct SimConfig {
  host_sim::DeviceParams device = host_sim::falcon_params();
  host_sim::PlantOptions plant;  ///< integrator, sub-steps, servo period
  std::uint64_t seed = 1;        ///< sensor noise (only drawn when the device has noise)
  ScalarKind scalar = ScalarKind::kDouble;
};

/// One servo tick: the loop's telemetry frame (what `run` reports), and what only a
/// simulation knows.
struct SimRecord {
  TelemetryFrame frame;          ///< the servo loop's, after the tick
  Vec3<double> true_position_m;  ///< the handle at t (not delayed, not quantised)
  Vec3<double> true_velocity_m_per_s;
  Vec3<double> hand_target_m;   ///< the hand's reference r at t
  Vec3<double> device_force_n;  ///< what the device applied over [t, t + period)
  std::size_t segment = 0;      ///< hand script segment (== count after the script)
  bool grasping = true;
};

/// A scene, a hand and a device, run tick by tick. The loop's scalar is chosen at run time;
/// step() is allocation-free.
class SimSession {
 public:
  static Result<SimSession> create(const SceneDescription& scene, const HandScriptFile& hand, const SimConfig& config);
  ~SimSession();
  SimSession(SimSession&&) noexcept;
  SimSession& operator=(SimSession&&) noexcept;

  /// Runs one tick and reports it.
  SimRecord step() noexcept;
  /// Ticks in `duration_s` at this period (rounded to the nearest tick).
  std::int64_t ticks_for(double duration_s) const noexcept;
  const host_sim::SimDevice& device() const noexcept;
  /// The simulated device, to set a starting state before the first step (tests).
  host_sim::SimDevice& device() noexcept;
  const SimConfig& config() const noexcept;
  /// The loop's configuration (the scene's, completed by the simulated device's figures).
  const ServoConfig& servo_config() const noexcept;
  /// The names of the effects' values in SimRecord::frame.values ("surface1.impact_t", ...).
  const std::vector<std::string>& value_names() const noexcept;
  /// Index of a value by name in frame.values, or value_names().size() if none.
  std::size_t value_index(std::string_view name) const noexcept;
  /// The last tick as the loop's telemetry frame (a stop: the shutdown tick's zero force).
  SimRecord shutdown() noexcept;

 private:
  struct Impl;
  explicit SimSession(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

/// A record's value by name (NaN if the scene has no such value).
double value_of(const SimRecord& record, const std::vector<std::string>& names, std::string_view name) noexcept;

}  // namespace toonforce
