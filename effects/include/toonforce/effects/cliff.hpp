// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The cartoon cliff: you fall only once you slow down (paper §4.3; spec effects.md §5).
///
/// A ground plane (p0, n) with a gap: the strip a_min <= a.(x - p0) <= a_max along the lateral
/// unit axis a. The HIP's lateral speed s = |v_t| is low-pass filtered every tick, wherever the
/// HIP is: s_f += dt/(tau + dt) (s - s_f), s_f = 0 at the start. Two states, from SUPPORTED:
///   SUPPORTED -> FALLEN  in the strip and s_f < speed_threshold;
///   FALLEN -> SUPPORTED  at least rearm_height above ground and (outside the strip or
///                        s_f >= speed_threshold), so a surface never appears with the HIP in it.
/// Forces: SUPPORTED, a penalty wall on the whole ground (the gap is bridged), no side faces.
/// FALLEN, no upward force over the strip and fall_force along -n there; outside the strip and
/// below ground (the HIP went sideways under a ledge) only the ledge's side face pushes, along
/// +-a toward the strip, k times the distance past the edge.

#include <array>
#include <cmath>

#include "toonforce/effects/penalty_wall.hpp"

namespace toonforce {

template <Scalar S>
struct CartoonCliff {
  using Scalar = S;
  static constexpr std::string_view kKey = "cliff";
  static constexpr std::size_t kMaxPerScene = 8;
  struct Params {
    Plane<S> ground;
    Vec3<S> axis;                            ///< a, unit, perpendicular to the ground normal
    S gap_min_m{};                           ///< [m] along a from p0 (required, < gap_max)
    S gap_max_m{};                           ///< [m] (required)
    typename PenaltyWall<S>::Params wall{};  ///< `stiffness` (required), `damping` (default 0)
    S speed_threshold_m_per_s{};             ///< [m/s], > 0 (required)
    S tau_s{};                               ///< filter time constant [s], >= 0 (default 0.02)
    S rearm_height_m{};                      ///< [m], >= 0 (default 0.001)
    S fall_force_n{};                        ///< [N], >= 0 (default 0)
  };
  struct State {
    S filtered_speed_m_per_s{};  ///< s_f
    bool fallen = false;
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr std::array<ValueInfo, 2> kValues{
      {{"state", "", "0 supported, 1 fallen"}, {"speed", "m/s", "filtered lateral speed s_f"}}};

  /// Scene-file keys of `[[cliff]]` (spec effects.md §5, interfaces.md).
  static constexpr auto schema() {
    using namespace schema;
    return fields(inline_fields(&Params::ground, Plane<S>::schema()), unit_vector("axis", &Params::axis),
                  number("gap_min", &Params::gap_min_m, "m", Range::kAny),
                  number("gap_max", &Params::gap_max_m, "m", Range::kAny),
                  inline_fields(&Params::wall, PenaltyWall<S>::schema()),
                  number("speed_threshold", &Params::speed_threshold_m_per_s, "m/s", Range::kPositive),
                  number("tau", &Params::tau_s, "s", Range::kNonNegative, 0.02),
                  number("rearm_height", &Params::rearm_height_m, "m", Range::kNonNegative, 0.001),
                  number("fall_force", &Params::fall_force_n, "N", Range::kNonNegative, 0.0));
  }
  /// The gap runs across the ground: the axis lies in the ground plane, gap_min < gap_max.
  /// A file's values are checked in double; a live update's as S holds them, whose rounding
  /// (Q16.16: up to 2^-17 a component) leaves two perpendicular unit vectors up to about 3e-5
  /// off, hence the larger tolerance there.
  static void check(const Params& p, schema::Problems& problems, ScalarKind) {
    constexpr double kTolerance = kIsFixed<S> ? 1e-4 : 1e-6;
    const double across = std::fabs(to_double(dot(p.ground.normal, p.axis)));
    if (!(across <= kTolerance))
      problems.add("axis", "must be perpendicular to the normal; |axis.normal| after normalising is", across);
    if (!(p.gap_min_m < p.gap_max_m)) problems.add("gap_max", "must be greater than gap_min");
  }
  static constexpr Needs needs(const Params&) noexcept { return kNeeds; }

  static constexpr Vec3<S> force(const Params& p, State& s, const TickInput<S>& in) noexcept {
    const Vec3<S>& n = p.ground.normal;
    const Contact<S> c = p.ground.contact(in);
    const S lateral_speed = norm(tangential_part(in.velocity_m_per_s, n, c.normal_speed_m_per_s));
    // dt/(tau + dt) written with the rate 1/dt: 1 / (1 + tau/dt). In a Q format the gain is
    // that reciprocal (one 32-bit division: the denominator is at least 1) times the step,
    // rounded twice; no 64-bit division on the tick.
    constexpr S kOne = scalar_cast<S>(1.0);
    if constexpr (kIsFixed<S>) {
      // Both speeds are >= 0 (a norm, and its filter from 0), so their difference is in range;
      // a gain in (0, 1] keeps the step within it and the new value between the two: no
      // saturation test but the gain's own. The values are operator-'s, * and +'s.
      const S gain = S::reciprocal_of_at_least_one(kOne + p.tau_s * in.rate_hz);
      const typename S::Raw filtered = s.filtered_speed_m_per_s.raw();
      const typename S::Raw difference = lateral_speed.raw() - filtered;
      s.filtered_speed_m_per_s =
          S::from_raw(filtered + S::from_product_in_range(typename S::Wide{difference} * gain.raw()).raw());
    } else {
      s.filtered_speed_m_per_s += (lateral_speed - s.filtered_speed_m_per_s) / (kOne + p.tau_s * in.rate_hz);
    }

    const S across = dot_unit_difference(p.axis, in.position_m, p.ground.point_m);
    const bool in_strip = p.gap_min_m <= across && across <= p.gap_max_m;
    const bool slow = s.filtered_speed_m_per_s < p.speed_threshold_m_per_s;
    if (!s.fallen) {
      s.fallen = in_strip && slow;
    } else if (c.penetration_m <= -p.rearm_height_m && (!in_strip || !slow)) {
      s.fallen = false;
    }

    if (!s.fallen) return times_in_range(n, PenaltyWall<S>::normal_force(p.wall, c));  // unit n, push >= 0
    // A unit vector times a force none of whose components can leave the range, so without the
    // saturation test (times_in_range): the fall force and a ledge's push are >= 0
    // (scene files: fall_force >= 0, stiffness > 0), and either negated is never lowest().
    if (in_strip) return times_in_range(n, -p.fall_force_n);
    if (c.penetration_m > S{}) {  // under a ledge: its side face pushes back toward the strip
      if (across < p.gap_min_m) return times_in_range(p.axis, p.wall.stiffness_n_per_m * (p.gap_min_m - across));
      return times_in_range(p.axis, -(p.wall.stiffness_n_per_m * (across - p.gap_max_m)));
    }
    return {};
  }

  /// A live scene's one-shot event (docs/spec/live-scenes.md): "look_down" zeroes
  /// the filtered lateral speed s_f, as a cartoon character stops and looks down. Over the gap
  /// the next tick's filter leaves s_f below the threshold unless the HIP is that fast within
  /// one tick, so it falls by §5's own rule; elsewhere it walks on (s_f recovers with tau).
  static constexpr std::array<std::string_view, 1> kEvents{"look_down"};
  static constexpr bool fire(const Params&, State& s, std::size_t event, double, Instant) noexcept {
    if (event != 0) return false;
    s.filtered_speed_m_per_s = S{};
    return true;
  }

  /// `state` and `speed`; true while the HIP is in the supported ground.
  static constexpr bool describe(const Params& p, const State& s, const TickInput<S>& in, double* values) noexcept {
    values[0] = s.fallen ? 1.0 : 0.0;
    values[1] = to_double(s.filtered_speed_m_per_s);
    return !s.fallen && p.ground.contact(in).penetration_m > S{};
  }
};

}  // namespace toonforce
