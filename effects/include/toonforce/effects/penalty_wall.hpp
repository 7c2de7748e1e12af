#pragma once
/// Penalty wall, the realistic baseline (paper §4.2; spec effects.md §1):
///   F_n = max(0, k delta - b (n.v)) along n while delta > 0, else 0.
/// Damping acts only inside and never pulls the HIP into the wall, hence the max.

#include "toonforce/effects/tick.hpp"

namespace toonforce {

/// `kDamped = false` is the spring-only wall: it needs no velocity, so a scene made only of
/// such walls runs no velocity estimator at all.
template <Scalar S, bool kDamped = true>
struct PenaltyWall {
  using Scalar = S;
  struct Params {
    S stiffness_n_per_m{};   ///< k [N/m], > 0 (scene key `stiffness`, required)
    S damping_n_s_per_m{};   ///< b [N s/m], >= 0 (scene key `damping`, default 0)
  };
  static constexpr Needs kNeeds = kDamped ? Needs::kVelocity : Needs::kNone;

  /// The magnitude of the wall force along +n [N]; zero out of contact (delta <= 0).
  static constexpr S normal_force(const Params& p, const Contact<S>& c) noexcept {
    if (!(c.penetration_m > S{})) return S{};
    S push = p.stiffness_n_per_m * c.penetration_m;
    if constexpr (kDamped) push = push - p.damping_n_s_per_m * c.normal_speed_m_per_s;
    return max(S{}, push);
  }
};

/// A wall without damping (see PenaltyWall).
template <Scalar S>
using SpringWall = PenaltyWall<S, false>;

}  // namespace toonforce
