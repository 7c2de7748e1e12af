// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Where and how fast the handle may be while force flows (spec effects.md §6): above
/// `max_velocity` (OpenHaptics-style software velocity limit) or outside the workspace box
/// (scene frame), the force is off for that tick and the fault says which. `NoMotionLimits`
/// checks nothing (replay: effects.md §6 only).

#include "toonforce/control/faults.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

struct MotionLimitsConfig {
  bool has_max_velocity = true;
  double max_velocity_m_per_s = 1.2;  ///< [m/s]
  bool has_workspace = false;
  Vec3<double> workspace_min_m;  ///< [m] scene frame
  Vec3<double> workspace_max_m;
};

template <Scalar S>
class MotionLimits {
 public:
  constexpr explicit MotionLimits(const MotionLimitsConfig& c) noexcept
      : max_speed_squared_(squared_limit<S>(c.has_max_velocity ? c.max_velocity_m_per_s : 0.0)),
        min_m_(vec_cast<S>(c.workspace_min_m)),
        max_m_(vec_cast<S>(c.workspace_max_m)),
        has_max_velocity_(c.has_max_velocity),
        has_workspace_(c.has_workspace) {}

  /// kOverspeed and kOutsideWorkspace as they apply to this tick.
  FaultSet check(const Vec3<S>& position_m, const Vec3<S>& velocity_m_per_s) const noexcept {
    // |v| > v_max as |v|^2 > v_max^2: no square root on every tick (and exact in Q16.16,
    // whose rounded squares let 0.0107 m/s pass a 0.01 m/s limit).
    // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
    // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM r2p1
    // table 3-1); no value changes.
    const bool overspeed =
        __builtin_expect(has_max_velocity_, true) && norm_exceeds(velocity_m_per_s, max_speed_squared_);
    const bool outside = has_workspace_ && !inside(position_m);
    return FaultSet((overspeed ? static_cast<std::uint32_t>(Fault::kOverspeed) : 0U) |
                    (outside ? static_cast<std::uint32_t>(Fault::kOutsideWorkspace) : 0U));
  }
  /// The velocity limit needs a velocity estimate.
  constexpr bool needs_velocity() const noexcept { return has_max_velocity_; }

 private:
  bool inside(const Vec3<S>& x) const noexcept {
    // & rather than &&: six comparisons and no branch (the tick's cost does not depend on where
    // the handle is).
    return static_cast<bool>(static_cast<int>(min_m_.x <= x.x) & static_cast<int>(x.x <= max_m_.x) &
                             static_cast<int>(min_m_.y <= x.y) & static_cast<int>(x.y <= max_m_.y) &
                             static_cast<int>(min_m_.z <= x.z) & static_cast<int>(x.z <= max_m_.z));
  }
  SquaredLimit<S> max_speed_squared_;  ///< [m^2/s^2]
  Vec3<S> min_m_;
  Vec3<S> max_m_;
  bool has_max_velocity_;
  bool has_workspace_;
};

template <Scalar S>
class NoMotionLimits {
 public:
  constexpr explicit NoMotionLimits(const MotionLimitsConfig&) noexcept {}
  FaultSet check(const Vec3<S>&, const Vec3<S>&) const noexcept { return {}; }
  constexpr bool needs_velocity() const noexcept { return false; }
};

}  // namespace toonforce
