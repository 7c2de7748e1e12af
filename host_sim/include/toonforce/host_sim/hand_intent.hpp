// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What the simulated hand intends at any instant: the point it aims for (its reference r and
/// the reference's velocity), the force it presses with, and whether it grasps the handle. The
/// intent is planned once from a HandScript (start-up code, may allocate) and then evaluated
/// at any time without allocating (the sub-steps of an integrator call it).
///
/// Time laws (docs/HAND_SCRIPTS.md):
/// - move: minimum-jerk from rest to rest (Flash & Hogan, J. Neurosci. 5(7), 1985),
///   s(tau) = L (10 tau^3 - 15 tau^4 + 6 tau^5);
/// - stroke, strike, cross: along the straight line to `to`, the speed changes from the entry
///   speed (the previous segment's exit velocity along this direction, never negative) to
///   `speed` over `ramp` seconds with a smoothstep (3 tau^2 - 2 tau^3, so the acceleration is
///   continuous), cruises, and with `stop` comes to rest at `to` over another `ramp`;
/// - hold, release: the reference stays where it is; release ends the grasp.
/// The press force (along -normal) changes linearly from its previous value to the segment's
/// over `force_ramp` seconds. After the last segment the hand keeps its last intent.
/// Not thread-safe: at() moves a cursor (one simulation per thread, as the servo loop runs).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/host_sim/hand_script.hpp"

namespace toonforce::host_sim {

/// The intent at one instant.
struct HandTarget {
  Vec3<double> position_m;        ///< r: where the hand aims to hold the handle
  Vec3<double> velocity_m_per_s;  ///< dr/dt
  Vec3<double> force_n;           ///< feed-forward force the hand applies (press force)
  bool grasping = true;           ///< false once released: the hand exerts nothing
  std::size_t segment = 0;        ///< index of the segment (== count after the script ends)
};

/// Why a script cannot be planned: which segment (index into HandScript::segments), which key.
struct PlanError {
  std::size_t segment = 0;
  std::string key;
  std::string problem;
};

class HandIntent {
 public:
  /// Plans `script`; on failure returns nullopt and fills `error`.
  static std::optional<HandIntent> plan(const HandScript& script, PlanError& error);

  /// The intent at time t [s] (t >= 0). Consecutive calls with non-decreasing t cost O(1).
  HandTarget at(double t_s) const noexcept;

  /// [s] when the last segment ends (a release without duration ends at its start).
  double duration_s() const noexcept { return duration_s_; }
  const HandImpedance& impedance() const noexcept { return impedance_; }
  const Vec3<double>& start_m() const noexcept { return start_m_; }
  std::size_t segment_count() const noexcept { return segments_.size(); }
  /// [s] start time of segment i.
  double segment_start_s(std::size_t i) const noexcept { return segments_[i].t0_s; }
  /// The time a hand released the handle, or nullopt.
  std::optional<double> release_time_s() const noexcept { return release_s_; }

  /// A hand that holds the handle at `where` forever (for tests and the real-time sim device).
  static HandIntent holding(const Vec3<double>& where, const HandImpedance& impedance = {});

 private:
  enum class Law : std::uint8_t { kStill, kMinimumJerk, kCruise };
  struct Planned {
    Law law = Law::kStill;
    double t0_s = 0.0;
    double duration_s = 0.0;
    Vec3<double> from_m;
    Vec3<double> to_m;
    Vec3<double> direction;  ///< unit, along the path
    double length_m = 0.0;
    // kCruise: entry, cruise and exit speeds, and the durations of the three phases.
    double v_in = 0.0, v_cruise = 0.0, v_out = 0.0;
    double t_in_s = 0.0, t_cruise_s = 0.0, t_out_s = 0.0;
    // Press force: from force_from_n to force_to_n over force_ramp_s.
    Vec3<double> force_from_n;
    Vec3<double> force_to_n;
    double force_ramp_s = 0.0;
    bool grasping = true;
  };

  /// Distance along the path and speed at `t` seconds into a planned segment.
  static void progress(const Planned& p, double t_s, double& s_m, double& v_m_per_s) noexcept;
  static Vec3<double> force_at(const Planned& p, double t_s) noexcept;

  std::vector<Planned> segments_;
  HandImpedance impedance_;
  Vec3<double> start_m_;
  double duration_s_ = 0.0;
  std::optional<double> release_s_;
  mutable std::size_t cursor_ = 0;  // last segment found: evaluation moves forward in time
};

}  // namespace toonforce::host_sim
