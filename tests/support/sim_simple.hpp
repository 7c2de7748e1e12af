// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A light-weight simulated device for the servo loop's tests (`toonforce run --device sim` uses
/// the host simulation, host_sim/). It exercises what host_sim's SimDriver does not: a device
/// on its own clock (real-time mode). Deliberately minimal: a point mass with viscous
/// damping (the handle), held by a spring-damper "hand" that follows a looped script of key
/// positions, so a run touches the bundled scenes' floor (z = 0) and strokes across it.
///
///   m a = F_device + k_h (p(t) - x) + b_h (p'(t) - v) - b_d v
///
/// integrated with semi-implicit Euler in sub-steps of at most `step_s`. In real-time mode each
/// read() advances the simulation to CLOCK_MONOTONIC "now" (the device's own clock, as a USB
/// device's would run), holding the last written force; in fixed mode each read() after the
/// first advances exactly `exchange_period_s` (deterministic, for tests). No velocity is
/// reported, like the Falcon: the loop estimates it. emergency_zero() may be called from any
/// thread; it zeroes the held force until the next write().

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "toonforce/hal/device.hpp"

namespace toonforce {

struct SimpleSimConfig {
  struct Keyframe {
    double t_s = 0.0;  ///< [s] from the start of the loop, increasing
    Vec3<double> position_m;
  };
  double mass_kg = 0.1;                   ///< handle and hand mass
  double device_damping_n_s_per_m = 0.5;  ///< the mechanism's own friction
  double hand_stiffness_n_per_m = 200.0;  ///< the grip
  double hand_damping_n_s_per_m = 3.0;
  double step_s = 1e-4;   ///< largest integration sub-step [s]
  bool real_time = true;  ///< advance with the clock, else exchange_period_s per read
  double exchange_period_s = 1e-3;
  double max_advance_s = 0.05;  ///< after a longer stall, only this much is simulated
  /// The hand's target, linearly interpolated and looped over the last key's time. Empty: the
  /// default stroke (hover at z = 2 cm, strike the floor at 0.16 m/s, stroke along +x at
  /// 0.1 m/s 4 mm "below" it, lift, return; 3 s per loop).
  std::vector<Keyframe> script;
  DeviceInfo info = default_info();

  /// Falcon-class figures (CHAI3D's nominal 8 N; a 12 cm cube around the centre).
  static DeviceInfo default_info();
  static std::vector<Keyframe> default_script();
};

class SimpleSimDevice final : public DeviceDriver {
 public:
  explicit SimpleSimDevice(SimpleSimConfig config = {});

  DeviceStatus read(DeviceReading& reading) noexcept override;
  DeviceStatus write(const Vec3<double>& force_n) noexcept override;
  void emergency_zero() noexcept override;
  const DeviceInfo& info() const noexcept override { return config_.info; }

  /// Simulated time [s] and state (tests).
  double time_s() const noexcept { return time_s_; }
  const Vec3<double>& position_m() const noexcept { return position_m_; }
  const Vec3<double>& velocity_m_per_s() const noexcept { return velocity_m_per_s_; }
  /// The hand's target at simulated time t.
  Vec3<double> target_m(double t_s) const noexcept;
  /// Work the device force has done on the handle so far [J] (tests: an oracle for the
  /// passivity controller, independent of the loop's own bookkeeping).
  double device_work_j() const noexcept { return device_work_j_; }
  std::uint64_t emergency_zeros() const noexcept { return emergency_zeros_.load(std::memory_order_relaxed); }

 private:
  void advance(double dt_s) noexcept;
  Vec3<double> target_velocity_m_per_s(double t_s) const noexcept;

  SimpleSimConfig config_;
  double loop_s_ = 0.0;
  double time_s_ = 0.0;
  std::int64_t last_clock_ns_ = -1;
  bool first_read_ = true;
  Vec3<double> position_m_;
  Vec3<double> velocity_m_per_s_;
  Vec3<double> force_n_;
  double device_work_j_ = 0.0;
  std::atomic<bool> zeroed_{false};
  std::atomic<std::uint64_t> emergency_zeros_{0};
};

/// The run-time factory `toonforce run --device sim` uses.
std::unique_ptr<DeviceDriver> make_simple_sim_device(const SimpleSimConfig& config = {});

}  // namespace toonforce
