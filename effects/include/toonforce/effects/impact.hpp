#pragma once
/// Exaggerated recoil and oscillation on impact (paper §4.2; spec effects.md §4).
///
/// Trigger: a tick on which the HIP enters contact (delta goes from <= 0 to > 0) with impact
/// speed v_i = -(n.v) >= min_impact_speed while armed. A trigger disarms; the effect re-arms
/// once the HIP is out by rearm_distance (delta <= -rearm_distance). A slower entry neither
/// triggers nor disarms; a trigger while a transient runs restarts it with the new v_i.
/// For 0 <= t <= d, along +n:
///   F = v_i (d - t) (k_r + k_osc sin(omega t)),  omega = 2 pi f,
/// signed (for k_osc > k_r it pulls toward the wall for part of each cycle, as the paper's
/// equations say), and it runs its whole duration whether or not the HIP stays in contact
/// (paper figure 3). The penalty wall acts as usual alongside.

#include "toonforce/effects/tick.hpp"
#include "toonforce/math/sine.hpp"

namespace toonforce {

/// No impact transient: a plain surface.
template <Scalar S>
struct NoImpact {
  struct Params {};
  struct State {};
  static constexpr Needs kNeeds = Needs::kNone;
  static constexpr bool kActive = false;
  static constexpr S force(const Params&, State&, const Contact<S>&, const TickInput<S>&) noexcept {
    return S{};
  }
};

template <Scalar S>
struct ImpactTransient {
  struct Params {
    S recoil_gain_n_per_m{};         ///< k_r [N/m] (required)
    S oscillation_gain_n_per_m{};    ///< k_osc [N/m] (required)
    S duration_s{};                  ///< d [s], > 0 (required)
    S frequency_hz{};                ///< f [Hz], > 0 (required)
    S min_impact_speed_m_per_s{};    ///< [m/s], >= 0 (default 0.05)
    S rearm_distance_m{};            ///< [m], >= 0 (default 0.001)
    SineMethod sine = default_sine_method<S>();
  };
  struct State {
    Instant trigger{};                 ///< tick of the running transient's trigger
    S impact_speed_m_per_s{};          ///< v_i of the running transient
    S previous_penetration_m{};        ///< delta of the previous tick
    bool started = false;              ///< false before the first tick (previous delta = current)
    bool armed = true;
    bool running = false;
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kActive = true;

  /// The transient's force along +n [N]; updates the trigger state.
  static constexpr S force(const Params& p, State& s, const Contact<S>& c,
                           const TickInput<S>& in) noexcept {
    const S delta = c.penetration_m;
    const S previous = s.started ? s.previous_penetration_m : delta;  // first tick: no entry
    s.started = true;
    s.previous_penetration_m = delta;

    if (!s.armed && delta <= -p.rearm_distance_m) s.armed = true;
    const S impact_speed = -c.normal_speed_m_per_s;
    const bool enters = !(previous > S{}) && delta > S{};
    if (enters && s.armed && impact_speed >= p.min_impact_speed_m_per_s) {
      s.armed = false;
      s.running = true;
      s.trigger = in.now;
      s.impact_speed_m_per_s = impact_speed;
    }
    if (!s.running) return S{};

    const double elapsed_s = in.seconds_since(s.trigger);
    if (!(elapsed_s <= to_double(p.duration_s))) {  // past d: the transient is over
      s.running = false;
      return S{};
    }
    const S t = scalar_cast<S>(elapsed_s);
    const S oscillation = sin_turns(p.frequency_hz * t, p.sine);
    return s.impact_speed_m_per_s * (p.duration_s - t) *
           (p.recoil_gain_n_per_m + p.oscillation_gain_n_per_m * oscillation);
  }

  /// Seconds since the trigger of the running transient, or NaN.
  static constexpr double time_since_trigger(const State& s, const TickInput<S>& in) noexcept {
    return s.running ? in.seconds_since(s.trigger) : std::numeric_limits<double>::quiet_NaN();
  }
};

/// An impact transient that a scene file may or may not configure (chosen at run time).
template <Scalar S>
struct MaybeImpact {
  struct Params {
    bool enabled = false;
    typename ImpactTransient<S>::Params law{};
  };
  using State = typename ImpactTransient<S>::State;
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kActive = true;

  static constexpr S force(const Params& p, State& s, const Contact<S>& c,
                           const TickInput<S>& in) noexcept {
    return p.enabled ? ImpactTransient<S>::force(p.law, s, c, in) : S{};
  }
  static constexpr double time_since_trigger(const State& s, const TickInput<S>& in) noexcept {
    return ImpactTransient<S>::time_since_trigger(s, in);
  }
};

}  // namespace toonforce
