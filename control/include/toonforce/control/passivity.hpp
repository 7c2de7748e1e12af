// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Passivity observer and controller (Hannaford and Ryu, "Time-domain passivity control of
/// haptic interfaces", IEEE T-RA 18(1):1-10, 2002).
///
/// Observer: the energy the virtual environment has absorbed, E_obs = -sum F_{k-1}.(x_k -
/// x_{k-1}), the zero-order-hold form (the force commanded at tick k-1 acts while the HIP
/// moves to x_k; Ryu, Kim and Hannaford, ICRA 2004 use the same). It needs no velocity
/// estimate, so filter lag cannot hide energy. E_obs >= 0 means passive so far; the
/// super-slippery surface and the impact transient drive it down by design.
///
/// Controller (spec effects.md §6): each active part of an effect (its ActiveForce slots, which
/// the effect reports itself, effects/effect.hpp) has an energy
/// budget per episode (a contact, a transient). Its episode energy E_i is the work its own
/// force did on the HIP (the share of it that reached the device), minus what the controller
/// dissipated on its behalf. Only the excess X_i = E_i - budget is dissipated, by a damping
/// force along -v of magnitude X_i / (|v| dt) (the HR rule alpha = X / (v^2 dt), written with
/// the rate 1/dt), so the cartoon effects play in full until they have injected their budget
/// and runaway energy cannot build up. The work is measured, not predicted: whatever the
/// clamp, the rate limit or the hand did to the damping shows in the next tick's E_i.
/// The damping coefficient is capped at max_damping: HR's alpha grows without bound as v -> 0,
/// and a large damper acting on a filtered, one-tick-late velocity on a light handle reverses
/// its motion within a few ticks and chatters, injecting energy instead (seen in the tests on
/// a 0.1 kg handle: +-7 N at 0.03 m/s). With the cap the controller removes at most
/// max_damping |v|^2 per second: an effect that injects faster than that (alpha > max_damping)
/// exceeds its budget until it stops or the hand speeds up. The slippery surface needs alpha
/// = |F_t|/|v| <= mu, so max_damping >= mu holds it to its budget.
/// Below kMinSpeed the velocity is noise and nothing is dissipated (the excess waits).
/// An episode's debt is dropped when the episode ends (the effect no longer injects); a new
/// episode starts at zero.

#include <array>
#include <cstddef>
#include <cstdint>

#include "toonforce/control/hip_sensor.hpp"
#include "toonforce/effects/tick.hpp"
#include "toonforce/math/loop_bound.hpp"
#include "toonforce/math/wide.hpp"

namespace toonforce {

struct PassivityConfig {
  bool controller = true;  ///< scene key passivity_controller
  double budget_j = 0.5;   ///< [J] per active effect and episode (scene key passivity_budget)
  /// [N s/m] the largest damping the controller applies (scene key passivity_max_damping);
  /// keep it at or below the device's nominal maximum damping (CHAI3D: Falcon 20, Omni 5).
  double max_damping_n_s_per_m = 10.0;
};

/// Hannaford-Ryu observer, zero-order-hold form.
template <Scalar S>
class PassivityObserver {
 public:
  /// `held_force_n` acted on the HIP while it moved by `displacement_m`.
  constexpr void observe(const Vec3<S>& held_force_n, const Vec3<S>& displacement_m) noexcept {
    energy_ -= Wide<S>::dot(held_force_n, displacement_m);
  }
  /// E_obs [J]: >= 0 passive so far.
  constexpr Wide<S> energy() const noexcept { return energy_; }

 private:
  Wide<S> energy_{};
};

template <Scalar S, std::size_t kSlots>
class PassivityController {
 public:
  /// [m/s] below this speed no damping is applied.
  static constexpr double kMinSpeedMPerS = 1e-3;
  /// A compiled scene's few slots: the loops over them run to kSlots, a count GCC unrolls, and
  /// stop at the slots in use, so one slot is straight code (the loops' counters and
  /// back edges were 66-74 cycles of an image's bound). A run-time scene's many slots keep the
  /// loop to the slots in use (unrolled to its capacity, the double loop's mean grew 2
  /// instructions, past the 600-instruction budget).
  static constexpr bool kUnrolled = kSlots <= 4;
  /// [J] an excess is capped here before it is turned into a force (keeps X * rate in range).
  static constexpr double kMaxExcessJ = 1.0;
  static constexpr std::uint64_t kMaxExcessQ32 = static_cast<std::uint64_t>(kMaxExcessJ * 4294967296.0);  // [2^-32 J]
  /// [N] Q formats: max_force_n is capped here (a device's is below 100 N), so that each
  /// component of the damping, at most alpha |v| <= max_force_n, is far inside the range.
  static constexpr double kMaxFixedForceN = 16384.0;

  /// `max_force_n` caps each slot's damping force (the clamp caps the sum anyway).
  constexpr PassivityController(const PassivityConfig& config, double max_force_n) noexcept
      : enabled_(config.controller),
        budget_(Wide<S>::from_double(config.budget_j)),
        max_excess_(scalar_cast<S>(kMaxExcessJ)),
        min_speed_(scalar_cast<S>(kMinSpeedMPerS)),
        min_speed_squared_(min_speed_squared_of()),
        max_damping_n_s_per_m_(scalar_cast<S>(config.max_damping_n_s_per_m)),
        max_force_n_(scalar_cast<S>(kIsFixed<S> && max_force_n > kMaxFixedForceN ? kMaxFixedForceN : max_force_n)) {}

  /// Books the interval that just ended: the previous tick's forces, times `applied` (the share
  /// of the wanted force that reached the device, 0..1), moved the HIP by `displacement_m`.
  constexpr void account(const Vec3<S>& displacement_m, S applied, std::size_t slots) noexcept {
    for (std::size_t i = 0; i < (kUnrolled ? kSlots : slots); ++i) {
      TOONFORCE_LOOP_BOUND(kSlots);  // slots <= kSlots: it indexes slots_
      if (kUnrolled && i >= slots) break;
      Slot& s = slots_[i];
      if (!s.in_episode) continue;
      if constexpr (kIsFixed<S>) {  // the work, then its share: one rounding, no Q16.16 product
        s.energy += Wide<S>::dot(s.force_n + s.damping_n, displacement_m).times_fraction(applied);
      } else {  // floating point: as it was (the figures' double runs unchanged)
        s.energy += Wide<S>::dot(s.force_n + s.damping_n, displacement_m * applied);
      }
    }
  }

  /// This tick's active forces (`slots` entries) and HIP velocity: tracks episodes and returns
  /// the damping force for the excess energies (zero when the controller is off).
  constexpr Vec3<S> update(const ActiveForce<S>* forces, std::size_t slots, const Vec3<S>& velocity_m_per_s,
                           S rate_hz) noexcept {
    bool episodes = false;
    return update(forces, slots, velocity_m_per_s, rate_hz, episodes);
  }
  /// The same, saying in `episodes` whether any slot is in an episode.
  constexpr Vec3<S> update(const ActiveForce<S>* forces, std::size_t slots, const Vec3<S>& velocity_m_per_s, S rate_hz,
                           bool& episodes) noexcept {
    episodes = false;
    damped_ = false;
    if constexpr (kSlots == 0) return Vec3<S>{};  // a scene without an active part: no loop to bound
    // The speed (a square root) only when some episode is over its budget: most ticks have none.
    // The damping is -v alpha, alpha = |F| / |v| = min(X rate / |v|^2, max_damping, max_force /
    // |v|) [N s/m] (the force X rate / |v|, capped at max_damping |v| and at max_force).
    bool speed_known = false;
    [[maybe_unused]] S speed{};
    [[maybe_unused]] S cap{};            // [N] (floating point)
    [[maybe_unused]] S inverse_speed{};  // [s/m] (Q formats) 0 while |v| <= kMinSpeed, else >= 2^-16
    [[maybe_unused]] S alpha_cap{};      // [N s/m] (Q formats) min(max_damping, max_force / |v|)
    Vec3<S> total{};
    for (std::size_t i = 0; i < (kUnrolled ? kSlots : slots); ++i) {  // as account()'s
      TOONFORCE_LOOP_BOUND(kSlots);                                   // slots <= kSlots: it indexes slots_
      if (kUnrolled && i >= slots) break;
      Slot& s = slots_[i];
      const ActiveForce<S>& f = forces[i];
      if (!f.in_episode) {  // no episode: nothing to book (account() skips the slot)
        s.in_episode = false;
        continue;
      }
      if (!s.in_episode || f.triggered) s.energy = Wide<S>{};  // a new episode
      s.in_episode = true;
      s.force_n = f.force_n;
      s.damping_n = Vec3<S>{};
      episodes = true;
      if (!enabled_ || !(s.energy > budget_)) continue;
      if (!speed_known) {
        if constexpr (kIsFixed<S>) {
          // 1 / |v| from the inverse root of the exact |v|^2: no root and no division (the
          // root, its reciprocal and four products were 180 instructions of the bound).
          const std::uint64_t squares = detail::raw_squares(velocity_m_per_s);
          if (squares > min_speed_squared_.value) {
            inverse_speed = S::from_raw(static_cast<typename S::Raw>(
                detail::times_inverse_root(1U, detail::inverse_root(squares))));  // |v| > 1e-3: below 2^31
            alpha_cap = at_most(raw_product(max_force_n_, inverse_speed), max_damping_n_s_per_m_);
          }
        } else {
          speed = norm(velocity_m_per_s);
          cap = min(max_damping_n_s_per_m_ * speed, max_force_n_);  // [N]
        }
        speed_known = true;
      }
      // Below kMinSpeed nothing is dissipated. (No flag of its own: one more instruction on every
      // tick of the double loop, whose 600-instruction budget the cartoon wall's just meets.)
      if constexpr (kIsFixed<S>) {
        if (inverse_speed.raw() == 0) continue;  // |v| < 56,756 m/s in Q16.16: 1 / |v| is never 0
      } else {
        if (!(speed > min_speed_)) continue;
      }
      S alpha;
      if constexpr (kIsFixed<S>) {
        // X = E - budget > 0 exactly as an unsigned difference of the raw energies, capped
        // before it is rounded; X rate <= rate, in range: no saturation test is needed.
        const std::uint64_t x = static_cast<std::uint64_t>(s.energy.raw()) - static_cast<std::uint64_t>(budget_.raw());
        static_assert(2 * S::kFracBits == 32, "a Q32.32 energy has a raw product's scale");
        // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's
        // static bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1
        // (Cortex-M3 TRM r2p1 table 3-1); no value changes.
        const S excess = __builtin_expect(x >= kMaxExcessQ32, 0) ? max_excess_ : rounded(static_cast<std::int64_t>(x));
        const S power = rounded(raw_product(excess, rate_hz));  // [W] > 0
        // X rate / |v|^2 as (X rate / |v|) / |v|, each product compared with its cap before it
        // is rounded, so neither saturates: a force X rate / |v| past the format's range is past
        // max_force, and then alpha is alpha_cap.
        const std::int64_t force = raw_product(power, inverse_speed);
        alpha =
            force >= scaled_up(S::max()) ? alpha_cap : at_most(raw_product(rounded(force), inverse_speed), alpha_cap);
      } else {  // as it was (the figures' double runs unchanged)
        const S excess = min((s.energy - budget_).to_scalar(), max_excess_);
        const S power = excess * rate_hz;  // [W] > 0
        const S magnitude = power < cap * speed ? power / speed : cap;
        alpha = magnitude / speed;
      }
      if constexpr (kIsFixed<S>) {
        s.damping_n = opposed(velocity_m_per_s, alpha);
      } else {
        s.damping_n = velocity_m_per_s * (-alpha);
      }
      if constexpr (kSlots == 1) {
        total = s.damping_n;  // 0 + d: no sum to saturate
      } else {
        total += s.damping_n;
      }
      damped_ = true;
    }
    return total;
  }
  /// The last update() damped some slot.
  constexpr bool damped() const noexcept { return damped_; }

  /// A live scene's update moved the active parts between slots: which episode is
  /// whose is no longer known, so every slot of the new layout continues an episode that has
  /// spent the most any running one had. Conservative: an update never gives an active part a
  /// fresh budget (a part not in an episode at its next tick starts one from zero, as always).
  constexpr void relayout(std::size_t old_slots, std::size_t new_slots) noexcept {
    Wide<S> most{};
    bool any = false;
    for (std::size_t i = 0; i < old_slots && i < slots_.size(); ++i) {
      if (!slots_[i].in_episode) continue;
      any = true;
      if (slots_[i].energy > most) most = slots_[i].energy;
    }
    for (std::size_t i = 0; i < new_slots && i < slots_.size(); ++i) slots_[i] = Slot{most, {}, {}, any};
  }

  /// The largest episode energy among running episodes [J] (0 if none).
  constexpr Wide<S> max_episode_energy(std::size_t slots) const noexcept {
    Wide<S> most{};
    for (std::size_t i = 0; i < slots; ++i) {
      TOONFORCE_LOOP_BOUND(kSlots);  // slots <= kSlots: it indexes slots_
      if (slots_[i].in_episode && slots_[i].energy > most) most = slots_[i].energy;
    }
    return most;
  }
  constexpr Wide<S> episode_energy(std::size_t slot) const noexcept { return slots_[slot].energy; }
  constexpr bool in_episode(std::size_t slot) const noexcept { return slots_[slot].in_episode; }
  constexpr bool enabled() const noexcept { return enabled_; }
  constexpr Wide<S> budget() const noexcept { return budget_; }

 private:
  struct Slot {
    Wide<S> energy{};     ///< E_i of the running episode [J]
    Vec3<S> force_n{};    ///< the effect's force on the previous tick
    Vec3<S> damping_n{};  ///< the damping applied on its behalf on the previous tick
    bool in_episode = false;
  };

  static constexpr auto min_speed_squared_of() noexcept {
    if constexpr (kIsFixed<S>) {
      return squared_limit<S>(kMinSpeedMPerS);
    } else {
      return NoSquare{};
    }
  }
  // Q formats only: a product of two raw values, exact in units of 2^-2F; one such p >= 0 below
  // max() 2^F rounded to S (no saturation test: it cannot saturate); min(p, cap) rounded, for
  // a cap >= 0, compared before the rounding, so it never saturates either.
  static constexpr S kOne = scalar_cast<S>(1.0);
  static constexpr std::int64_t raw_product(S a, S b) noexcept {
    auto x = a.raw();
    auto y = b.raw();
    detail::make_opaque(x, y);  // from rounded 64-bit products: one SMULL, not two MLAs and a UMULL
    return std::int64_t{x} * y;
  }
  static constexpr std::int64_t scaled_up(S cap) noexcept { return std::int64_t{cap.raw()} * kOne.raw(); }
  static constexpr S rounded(std::int64_t p) noexcept {
    return S::from_raw(static_cast<typename S::Raw>((p + (std::int64_t{1} << (S::kFracBits - 1))) >> S::kFracBits));
  }
  // (The hint: the dearer side in line, for the bound.)
  static constexpr S at_most(std::int64_t p, S cap) noexcept {
    return __builtin_expect(p >= scaled_up(cap), 0) ? cap : rounded(p);
  }
  // -alpha v, each product rounded as operator* rounds it (half away from zero, so the sign
  // can go on the result) without the saturation test (three of the bound's):
  // alpha <= max_force / |v| rounded up by at most 2^-17 N s/m (alpha_cap), so |alpha v_i| <=
  // max_force + |v| 2^-17 <= 16,384 + 0.25 N, far inside the range.
  static constexpr Vec3<S> opposed(const Vec3<S>& v, S alpha) noexcept {
    const auto times = [alpha](S c) { return S::from_raw(-S::from_product_in_range(raw_product(c, alpha)).raw()); };
    return {times(v.x), times(v.y), times(v.z)};
  }

  bool enabled_;
  Wide<S> budget_;
  S max_excess_;
  S min_speed_;  ///< floating point: the speed is compared
  struct NoSquare {};
  /// Q formats: the exact raw square is (the controller takes no root to test it).
  [[no_unique_address]] std::conditional_t<kIsFixed<S>, SquaredLimit<S>, NoSquare> min_speed_squared_;
  S max_damping_n_s_per_m_;
  S max_force_n_;
  std::array<Slot, (kSlots > 0 ? kSlots : 1)> slots_{};
  bool damped_ = false;
};

/// The passivity stage of the servo loop: the observer on every tick with a position, and the
/// controller's damping for the active parts' energy beyond their budget. It keeps what it
/// needs between ticks: the last good position and the share of the last tick's wanted force
/// that reached the device (the ramp, the rate limit and the clamp may have scaled it).
template <Scalar S, std::size_t kSlots>
class Passivity {
 public:
  /// `slots` of the scene's active parts are in use; `max_force_n` caps the damping; the
  /// controller turns an excess energy into a force over one period `period_s`.
  constexpr Passivity(const PassivityConfig& config, std::size_t slots, double max_force_n, double period_s) noexcept
      : controller_(config, max_force_n), slots_(slots), rate_hz_(scalar_cast<S>(1.0 / period_s)) {}

  /// Start of a tick: `held_force_n`, commanded since the last good position, moved the HIP to
  /// this tick's position (zero-order hold).
  void observe(const Vec3<S>& held_force_n, const Vec3<S>& position_m, bool position_finite) noexcept {
    if (!position_finite) return;
    observe_step(held_force_n, position_m - previous_m_, has_position_);
    previous_m_ = position_m;
    has_position_ = true;
  }
  /// The same with the HIP's step since the last good position already taken (`stepped`: there
  /// was a last position): a Q loop whose device reads in its scalar, where every tick with a
  /// position counts, so HipSensor's step since the last counted tick is this one (the
  /// stage kept its own last position and took the same difference again).
  void observe_step(const Vec3<S>& held_force_n, const Vec3<S>& step_m, bool stepped) noexcept {
    if (!stepped) return;
    observer_.observe(held_force_n, step_m);
    // (The hint: the dearer side in line, for the bound.)
    if (episodes_) [[likely]]
      controller_.account(step_m, applied_, slots_);  // only a running episode books work
  }
  /// After a tick that counted: the damping for this tick's active parts into `damping_n`
  /// (zero when none exceeds its budget or the controller is off); true if there is some.
  bool damping(const ActiveForce<S>* active, const Vec3<S>& velocity_m_per_s, Vec3<S>& damping_n) noexcept {
    damping_n = controller_.update(active, slots_, velocity_m_per_s, rate_hz_, episodes_);
    return controller_.damped();
  }
  /// End of a tick that commanded `out_n` for a wanted `wanted_n`: the share that reached the
  /// device, for the next interval's bookkeeping (only needed while an episode runs).
  void settle(const Vec3<S>& wanted_n, const Vec3<S>& out_n) noexcept {
    if (kSlots == 0 || !episodes_) {  // no active part, no episode: a constant the compiler sees
      applied_ = S{};
      return;
    }
    constexpr S kOne = scalar_cast<S>(1.0);
    if (out_n == wanted_n) {  // nothing scaled it (active, no limit bit): all of it
      applied_ = wanted_n == Vec3<S>{} ? S{} : kOne;
      return;
    }
    if constexpr (kIsFixed<S>) {
      static_assert(S::kFracBits == 16, "fraction_q16 gives 2^-16 units");
      // The share out.wanted / |wanted|^2 from the exact 64-bit sums (no Q16.16 square to
      // saturate past 181 N), as a fraction within 2^-15 of it: one 32-bit division
      // (detail::fraction_q16; a Q16.16 quotient and two rounded dot products were
      // the stage's dearest step after the update).
      const std::uint64_t wanted_squared = detail::raw_squares(wanted_n);
      const std::int64_t projection = Wide<S>::dot(out_n, wanted_n).raw();
      if (wanted_squared == 0 || projection <= 0) {
        applied_ = S{};
        return;
      }
      const auto p = static_cast<std::uint64_t>(projection);
      applied_ = p >= wanted_squared
                     ? kOne
                     : S::from_raw(static_cast<typename S::Raw>(detail::fraction_q16(p, wanted_squared)));
    } else {
      const S wanted_squared = dot(wanted_n, wanted_n);
      applied_ = wanted_squared > S{} ? max(S{}, min(kOne, dot(out_n, wanted_n) / wanted_squared)) : S{};
    }
  }
  /// End of a tick whose force was cut: nothing of the effects' forces reached the device.
  void cut() noexcept { applied_ = S{}; }

  /// A live scene's update: `slots` active parts from now on (PassivityController::relayout).
  void relayout(std::size_t slots) noexcept {
    controller_.relayout(slots_, slots);
    slots_ = slots < kSlots ? slots : kSlots;
  }

  /// Whether the controller may need the velocity (it damps along -v).
  constexpr bool needs_velocity() const noexcept { return controller_.enabled() && slots_ > 0; }
  const PassivityObserver<S>& observer() const noexcept { return observer_; }
  const PassivityController<S, kSlots>& controller() const noexcept { return controller_; }
  std::size_t slots() const noexcept { return slots_; }

 private:
  PassivityObserver<S> observer_;
  PassivityController<S, kSlots> controller_;
  std::size_t slots_;
  S rate_hz_;
  Vec3<S> previous_m_{};
  bool has_position_ = false;
  bool episodes_ = false;  ///< some active part is in an episode this tick
  S applied_{};
};

/// No passivity stage (replay: effects.md §6 only).
template <Scalar S, std::size_t kSlots>
class NoPassivity {
 public:
  constexpr NoPassivity(const PassivityConfig&, std::size_t, double, double) noexcept {}
  void observe(const Vec3<S>&, const Vec3<S>&, bool) noexcept {}
  void observe_step(const Vec3<S>&, const Vec3<S>&, bool) noexcept {}
  bool damping(const ActiveForce<S>*, const Vec3<S>&, Vec3<S>&) noexcept { return false; }
  void settle(const Vec3<S>&, const Vec3<S>&) noexcept {}
  void cut() noexcept {}
  void relayout(std::size_t) noexcept {}
  constexpr bool needs_velocity() const noexcept { return false; }
};

}  // namespace toonforce
