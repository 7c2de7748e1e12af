// SPDX-License-Identifier: Apache-2.0
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
///
/// The transient injects energy by design: it is an active part (one passivity slot), whose
/// episode is the running transient.

#include "toonforce/effects/tick.hpp"
#include "toonforce/math/sine.hpp"

namespace toonforce {

/// What the impact did on one tick.
template <Scalar S>
struct ImpactOutput {
  S force_n{};             ///< along +n [N]
  bool running = false;    ///< a transient runs after this tick
  bool triggered = false;  ///< it was (re)started on this tick
};

/// No impact transient: a plain surface.
template <Scalar S>
struct NoImpact {
  struct Params {};
  struct State {};
  static constexpr Needs kNeeds = Needs::kNone;
  static constexpr bool kPresent = false;
  static constexpr auto schema() { return schema::fields(); }
  static constexpr Needs needs(const Params&) noexcept { return Needs::kNone; }
  static constexpr ImpactOutput<S> force(const Params&, State&, const Contact<S>&, const TickInput<S>&) noexcept {
    return {};
  }
};

template <Scalar S>
struct ImpactTransient {
  struct Params {
    S recoil_gain_n_per_m{};              ///< k_r [N/m] (required)
    S oscillation_gain_n_per_m{};         ///< k_osc [N/m] (required)
    S duration_s{};                       ///< d [s], > 0 (required)
    S frequency_hz{};                     ///< f [Hz], > 0 (required)
    S min_impact_speed_m_per_s{};         ///< [m/s], >= 0 (default 0.05)
    S rearm_distance_m{};                 ///< [m], >= 0 (default 0.001)
    SineMethod sine = SineMethod::kAuto;  ///< kAuto: the scalar type's own default
  };
  struct State {
    Instant trigger{};         ///< tick of the running transient's trigger
    S impact_speed_m_per_s{};  ///< v_i of the running transient
    /// delta of the previous tick; before the first, a depth inside (1 m), so that the first
    /// tick is no entry whatever its delta (a flag for "no previous tick" was a branch the
    /// Cortex-M3 bound took out of line and back)
    S previous_penetration_m = scalar_cast<S>(1.0);
    bool armed = true;
    bool running = false;
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kPresent = true;
  static constexpr std::string_view kTableKey = "impact";

  /// Scene-file table `impact` (spec effects.md §4, interfaces.md).
  static constexpr auto schema() {
    using namespace schema;
    return fields(number("recoil_gain", &Params::recoil_gain_n_per_m, "N/m", Range::kAny),
                  number("oscillation_gain", &Params::oscillation_gain_n_per_m, "N/m", Range::kAny),
                  number("duration", &Params::duration_s, "s", Range::kPositive),
                  number("frequency", &Params::frequency_hz, "Hz", Range::kPositive),
                  number("min_impact_speed", &Params::min_impact_speed_m_per_s, "m/s", Range::kNonNegative, 0.05),
                  number("rearm_distance", &Params::rearm_distance_m, "m", Range::kNonNegative, 0.001),
                  choice("sine", &Params::sine, kSineNames, SineMethod::kAuto));
  }
  static constexpr std::array<std::pair<std::string_view, SineMethod>, 3> kSineNames{
      {{"library", SineMethod::kLibrary}, {"polynomial", SineMethod::kPolynomial}, {"table", SineMethod::kTable}}};

  /// What the keys cannot say alone: a library sine needs floating point, and the phase
  /// f * t must fit Q16.16 over the whole transient.
  static void check(const Params& p, schema::Problems& problems, ScalarKind scalar) {
    if (scalar != ScalarKind::kQ16_16) return;
    if (p.sine == SineMethod::kLibrary) {
      problems.add("sine", "'library' needs a floating-point scalar; use 'polynomial' or 'table' for q16.16");
    }
    const double turns = to_double(p.duration_s) * to_double(p.frequency_hz);
    if (!representable<Q16_16>(turns)) {
      problems.add("frequency", "frequency x duration (turns over the transient) is outside the Q16.16 range:", turns);
    }
  }

  /// The transient on this tick; updates the trigger state.
  static constexpr ImpactOutput<S> force(const Params& p, State& s, const Contact<S>& c,
                                         const TickInput<S>& in) noexcept {
    const S delta = c.penetration_m;
    const S previous = s.previous_penetration_m;  // first tick: inside, so no entry
    s.previous_penetration_m = delta;

    ImpactOutput<S> out;
    if (!s.armed && delta <= -p.rearm_distance_m) s.armed = true;
    const bool enters = !(previous > S{}) && delta > S{};
    if (enters && s.armed) {
      const S impact_speed = -c.normal_speed_m_per_s;
      if (impact_speed >= p.min_impact_speed_m_per_s) {
        s.armed = false;
        s.running = true;
        s.trigger = in.now;
        s.impact_speed_m_per_s = impact_speed;
        out.triggered = true;
      }
    }
    if (!s.running) return out;

    S t;      // since the trigger [s]
    S phase;  // f t [turns]
    S left;   // d - t [s]: taken before the sine in a Q format, after it in floating point, the
              // orders in which GCC schedules each loop shortest (7 instructions of the image's
              // bound; 3 of the double loop's mean, whose budget is 600)
    if constexpr (kIsFixed<S>) {
      // A Q scalar times in integer nanoseconds: t <= d tested exactly, t rounded once, no
      // floating point (an FPU-less target, tools/mcu). 2^46 ns is past any Q16.16 duration;
      // so is a trigger after this tick (ticks increase: it cannot happen), read unsigned.
      const auto elapsed_ns = static_cast<std::uint64_t>(in.ns_since(s.trigger));
      constexpr std::uint64_t kPastAnyDuration = std::uint64_t{1} << (62 - S::kFracBits);
      if (!(elapsed_ns < kPastAnyDuration &&
            p.duration_s.ratio_at_most(static_cast<std::int64_t>(elapsed_ns), kNsPerS))) {
        s.running = false;  // past d: the transient is over
        out.triggered = false;
        return out;
      }
      // 0 <= t <= d: neither t nor d - t can leave the range (no saturation tests).
      // Only the phase's fraction matters to the sine, and the low word of the rounded product
      // holds it exactly even where f t passes the range (scene files cannot: check()), so the
      // product is not saturated either.
      t = S::from_ns_in_range(elapsed_ns);
      phase = S::from_product_in_range(std::int64_t{p.frequency_hz.raw()} * t.raw());
      left = S::from_raw(p.duration_s.raw() - t.raw());
    } else {
      const double elapsed_s = in.seconds_since(s.trigger);
      if (!(elapsed_s <= to_double(p.duration_s))) {  // past d: the transient is over
        s.running = false;
        out.triggered = false;
        return out;
      }
      t = scalar_cast<S>(elapsed_s);
      phase = p.frequency_hz * t;
    }
    const S oscillation = sin_turns(phase, p.sine);
    if constexpr (!kIsFixed<S>) left = p.duration_s - t;
    out.running = true;
    out.force_n = s.impact_speed_m_per_s * left * (p.recoil_gain_n_per_m + p.oscillation_gain_n_per_m * oscillation);
    return out;
  }

  /// Starts the transient at `now` with v_i = `speed_m_per_s` (a live scene's event): the same
  /// state a trigger leaves, without disarming (the HIP did not enter). A transient already
  /// running restarts, as a trigger would (§4).
  static constexpr bool fire(const Params&, State& s, double speed_m_per_s, Instant now) noexcept {
    s.running = true;
    s.trigger = now;
    s.impact_speed_m_per_s = scalar_cast<S>(speed_m_per_s);
    return true;
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
  static constexpr bool kPresent = true;

  /// An optional scene-file table `impact`.
  static constexpr auto schema() {
    using namespace schema;
    return fields(table(ImpactTransient<S>::kTableKey, &Params::law, &Params::enabled, ImpactTransient<S>::schema()));
  }
  static void check(const Params& p, schema::Problems& problems, ScalarKind scalar) {
    if (!p.enabled) return;
    schema::SubTableProblems sub(problems, ImpactTransient<S>::kTableKey);
    ImpactTransient<S>::check(p.law, sub, scalar);
  }
  static constexpr Needs needs(const Params& p) noexcept { return p.enabled ? Needs::kVelocity : Needs::kNone; }

  static constexpr ImpactOutput<S> force(const Params& p, State& s, const Contact<S>& c,
                                         const TickInput<S>& in) noexcept {
    return p.enabled ? ImpactTransient<S>::force(p.law, s, c, in) : ImpactOutput<S>{};
  }
  static constexpr double time_since_trigger(const State& s, const TickInput<S>& in) noexcept {
    return ImpactTransient<S>::time_since_trigger(s, in);
  }
  static constexpr bool fire(const Params& p, State& s, double speed_m_per_s, Instant now) noexcept {
    return p.enabled && ImpactTransient<S>::fire(p.law, s, speed_m_per_s, now);
  }
};

}  // namespace toonforce
