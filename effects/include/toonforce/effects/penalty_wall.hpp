// SPDX-License-Identifier: Apache-2.0
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
    S stiffness_n_per_m{};  ///< k [N/m], > 0 (scene key `stiffness`, required)
    S damping_n_s_per_m{};  ///< b [N s/m], >= 0 (scene key `damping`, default 0)
  };
  static constexpr Needs kNeeds = kDamped ? Needs::kVelocity : Needs::kNone;

  /// Scene-file keys `stiffness` [N/m, required, > 0] and `damping` [N s/m, default 0, >= 0]
  /// (a spring-only wall has no damping key).
  static constexpr auto schema() {
    using namespace schema;
    const auto stiffness = number("stiffness", &Params::stiffness_n_per_m, "N/m", Range::kPositive);
    if constexpr (kDamped) {
      return fields(stiffness, number("damping", &Params::damping_n_s_per_m, "N s/m", Range::kNonNegative, 0.0));
    } else {
      return fields(stiffness);
    }
  }
  /// Whether this wall needs a velocity (a file's wall without damping needs none).
  static constexpr Needs needs(const Params& p) noexcept {
    return kDamped && p.damping_n_s_per_m != S{} ? Needs::kVelocity : Needs::kNone;
  }

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
