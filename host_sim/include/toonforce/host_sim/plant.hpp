// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The physical part of the host simulation: the device's handle and the hand that grasps it,
/// one rigid body in the scene frame, driven by the device force (held over each servo period)
/// and by the hand's arm impedance around its intent:
///
///   (m_d + m_h) a = F_device - b_d v - F_coulomb(v) + k_h (r - x) + b_h (dr/dt - v) + F_press
///
/// with F_coulomb = f_c v / sqrt(|v|^2 + v_s^2). After a release the hand's terms and mass drop
/// out. `step()` advances one servo period in `substeps` sub-steps of the chosen integrator;
/// it never allocates or throws, and the same inputs give the same bits (no clocks, no
/// threads, a fixed order of operations).

#include <array>
#include <cstdint>

#include "toonforce/common/result.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/host_sim/integrator.hpp"

namespace toonforce::host_sim {

struct PlantOptions {
  Integrator integrator = Integrator::kRk4;
  int substeps = 4;        ///< sub-steps per servo period, >= 1
  double period_s = 1e-3;  ///< servo period [s]
};

class Plant {
 public:
  /// Checks that the sub-step is short enough for the stiffest part of the model (with an
  /// explicit method, h times the fastest rate must stay <= 1) and says how many sub-steps
  /// would do if not.
  static Result<Plant> create(const DeviceParams& device, HandIntent intent, const PlantOptions& options);

  /// Advances from t = tick * period to the next tick with `force_n` held on the handle.
  void step(std::int64_t tick, const Vec3<double>& force_n) noexcept;

  const Vec3<double>& position_m() const noexcept { return x_; }
  const Vec3<double>& velocity_m_per_s() const noexcept { return v_; }
  void set_state(const Vec3<double>& position_m, const Vec3<double>& velocity_m_per_s) noexcept {
    x_ = position_m;
    v_ = velocity_m_per_s;
  }
  /// The hand's intent at time t.
  HandTarget hand(double t_s) const noexcept { return target_at(t_s); }
  const HandIntent& intent() const noexcept { return intent_; }
  /// Kinetic energy of the moving mass plus the hand spring's energy about its reference [J].
  double mechanical_energy_j(double t_s) const noexcept;
  /// Work the device force has done on the handle since the start [J] (exact for a held force).
  double device_work_j() const noexcept { return work_j_; }
  /// The fastest rate of the model [1/s] (what limits an explicit step) and the hand's
  /// spring frequency sqrt(k / m) [rad/s].
  double fastest_rate_per_s() const noexcept { return fastest_rate_per_s_; }
  double hand_omega_rad_per_s() const noexcept;
  const PlantOptions& options() const noexcept { return options_; }
  const DeviceParams& device() const noexcept { return device_; }

 private:
  /// The linear part while the hand grasps (index 1) or not (index 0), and for kExact the
  /// sub-step's transition: row r of [Phi | G0 | G1] gives x (r = 0) and v (r = 1) from
  /// (x0, v0, u0, du), the input u(s) = u0 + du s over the sub-step.
  struct Linear {
    double mass_kg = 0.0;
    double inverse_mass_per_kg = 0.0;
    double stiffness_n_per_m = 0.0;
    double damping_n_s_per_m = 0.0;  ///< device plus hand
    double hand_damping_n_s_per_m = 0.0;
    std::array<std::array<double, 4>, 2> transition{};
  };

  Plant(const DeviceParams& device, HandIntent intent, const PlantOptions& options);

  /// The intent at t, remembering the last two instants asked for: RK4 asks for the middle
  /// of a sub-step twice and for its end again as the next one's start, so a tick of s
  /// sub-steps evaluates the intent 2 s + 1 times instead of 5 s.
  const HandTarget& target_at(double t_s) const noexcept;

  Vec3<double> coulomb(const Vec3<double>& v) const noexcept;
  /// Everything but the linear part's -k x - b v: device force, friction, the hand's pull
  /// toward its reference and its press force.
  Vec3<double> input(const Linear& l, bool grasping, double t_s, const Vec3<double>& force_n,
                     const Vec3<double>& v) const noexcept;
  Vec3<double> acceleration(const Linear& l, bool grasping, double t_s, const Vec3<double>& force_n,
                            const Vec3<double>& x, const Vec3<double>& v) const noexcept;
  void substep(const Linear& l, bool grasping, double t_s, const Vec3<double>& force_n) noexcept;

  DeviceParams device_;
  HandIntent intent_;
  PlantOptions options_;
  double h_s_ = 0.0;
  std::array<Linear, 2> linear_{};
  double fastest_rate_per_s_ = 0.0;
  Vec3<double> x_;
  Vec3<double> v_;
  double work_j_ = 0.0;
  struct Remembered {
    double t_s = -1.0;  // the intent is only asked for t >= 0
    HandTarget target;
  };
  mutable std::array<Remembered, 2> remembered_{};
  mutable std::size_t next_slot_ = 0;
};

/// exp(A) of a 4x4 matrix by scaling and squaring of its Taylor series (start-up code; exposed
/// for the tests). Accurate to a few ulps for the small, well-scaled matrices used here.
std::array<std::array<double, 4>, 4> matrix_exponential(const std::array<std::array<double, 4>, 4>& a) noexcept;

}  // namespace toonforce::host_sim
