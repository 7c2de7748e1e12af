#pragma once
/// The closed loop of `toonforce sim`: every servo tick,
///   simulated device reading (delayed, quantised) -> Controller (the scene's own config)
///   -> force written (saturated, DAC-quantised, held over the tick) -> device and hand
///      advanced over the tick,
/// in simulated time, as fast as the machine goes, deterministically. The Controller is the
/// same one replay and the servo loop run. Until the servo loop (control/) lands, this is the
/// loop; afterwards it can become ServoLoop<SimDevice, ...> without changing its records.

#include <cstdint>
#include <memory>
#include <optional>

#include "toonforce/common/result.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce {

/// How to simulate: the device, the integration, the controller's scalar.
struct SimConfig {
  host_sim::DeviceParams device = host_sim::falcon_params();
  host_sim::PlantOptions plant;  ///< integrator, sub-steps, servo period
  std::uint64_t seed = 1;        ///< sensor noise (only drawn when the device has noise)
  ScalarKind scalar = ScalarKind::kDouble;
  std::optional<SineMethod> sine;  ///< overrides the scene's impact sine method
};

/// One servo tick, as the trace reports it.
struct SimRecord {
  std::int64_t tick = 0;
  double t_s = 0.0;                        ///< tick * period
  Vec3<double> position_m;                 ///< the reading the controller got
  Vec3<double> velocity_m_per_s;           ///< the velocity the scene used (0 if it needs none)
  Vec3<double> force_n;                    ///< commanded, after the safety stage
  std::uint32_t faults = 0;                ///< Fault bits
  std::uint8_t limits = 0;                 ///< Limit bits
  bool has_diagnostics = true;             ///< false on a tick whose effect states did not advance
  Diagnostics diagnostics;                 ///< contact, impact time, cliff state
  Vec3<double> true_position_m;            ///< the handle at t (not delayed, not quantised)
  Vec3<double> true_velocity_m_per_s;
  Vec3<double> hand_target_m;              ///< the hand's reference r at t
  Vec3<double> device_force_n;             ///< what the device applied over [t, t + period)
  std::size_t segment = 0;                 ///< hand script segment (== count after the script)
  bool grasping = true;
};

/// A scene, a hand and a device, run tick by tick. The controller's scalar is chosen at run
/// time; step() is allocation-free.
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
  /// The controller's force limits (the smaller of the scene's and the device's maximum).
  const ControllerConfig& controller_config() const noexcept;

 private:
  struct Impl;
  explicit SimSession(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

}  // namespace toonforce
