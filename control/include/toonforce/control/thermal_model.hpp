// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A first-order motor thermal model per device (after OpenHaptics' predicted
/// HD_MOTOR_TEMPERATURE, OpenHaptics Reference Guide; docs/OMNI.md §2.3). Copper losses grow
/// with the current squared, and the current with the force, so with theta the temperature
/// rise normalised to the rated one (0 cold, 1 rated):
///     tau dtheta/dt = (|F| / F_c)^2 - theta,
/// where F_c is the continuous force (held forever it settles exactly at the rated
/// temperature) and tau the thermal time constant. Discretised exactly for a force held over
/// each tick (zero-order hold): theta <- u + (theta - u) r^n, u = (|F|/F_c)^2, r = exp(-T/tau),
/// n the ticks the force was held (skipped ticks included), so at tick times it equals the
/// continuous closed form theta(t) = u + (theta_0 - u) exp(-t/tau).
///
/// Derating: the allowed force falls linearly from max_force at theta = derate_start to F_c at
/// theta = 1 and stays at F_c above: at F_c the temperature cannot rise past rated, so a user
/// pushing hard forever ends at the continuous force instead of burning the motors. The servo
/// loop gives the allowed force to the clamp (ForceSafety::set_max_force), which stays last.
/// With F_c >= max_force there is nothing to derate.
///
/// Cost per tick (a bound by construction): in the fixed-point build no tick raises
/// r to a power. r^n for the gaps a running loop has (1, a late tick, a few missed ones, up to
/// kTabulatedGaps) is a table computed at configuration time; a longer gap (past the
/// supervisor's default watchdog of 30 periods, which latches a fault) takes a factor that
/// over-estimates the temperature: r^kTabulatedGaps when cooling (less cooling than
/// r^n), 0 when heating (all the way to the target u, above u + (theta - u) r^n). So the
/// derating is never weaker than the exact model's. The floating-point builds keep r^n by
/// repeated squaring (their results unchanged; no bound is taken of them).
/// The heating u = |F|^2 / F_c^2 comes, in the fixed-point build, from the exact 64-bit squares
/// of the force times 1/F_c^2 held as a 32-bit mantissa and a shift (HeatScale, from the
/// configuration): one 64x32 product and the shifts, where scaling each component by 1/F_c
/// first took three saturating Q16.16 products and rounded 1/F_c to 2^-16 (u off by
/// up to a few 10^-5 of itself; now by about 2^-31).

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "toonforce/math/wide.hpp"

namespace toonforce {

struct ThermalConfig {
  double continuous_force_n = 0.0;  ///< F_c [N]; 0 turns the model off
  double time_constant_s = 60.0;    ///< tau [s] (scene key thermal_time_constant)
  double derate_start = 0.8;        ///< theta where derating begins, in [0, 1)
  constexpr bool enabled() const noexcept { return continuous_force_n > 0.0; }
};

template <Scalar S>
class ThermalModel {
 public:
  /// `max_force_n` > 0 is the undrated limit; `period_s` the servo period.
  constexpr ThermalModel(const ThermalConfig& config, double period_s, double max_force_n) noexcept
      : enabled_(config.enabled() && config.continuous_force_n < max_force_n),
        max_force_n_(scalar_cast<S>(max_force_n)),
        continuous_force_n_(scalar_cast<S>(enabled_ ? config.continuous_force_n : max_force_n)),
        decay_per_tick_(Decay<S>::from_double(std::exp(-period_s / config.time_constant_s))) {
    if constexpr (!kIsFixed<S>) {
      float_ = {scalar_cast<S>(enabled_ ? 1.0 / config.continuous_force_n : 0.0), scalar_cast<S>(config.derate_start),
                scalar_cast<S>(1.0 / (1.0 - config.derate_start))};
    } else {
      // r^n rounded once from the exact exponential (the first entry is decay_per_tick_).
      for (std::size_t i = 0; i < decay_by_gap_.size(); ++i) {
        const double ticks = static_cast<double>(i + 1);
        decay_by_gap_[i] = Decay<S>::from_double(std::exp(-ticks * period_s / config.time_constant_s));
      }
      if (enabled_) {
        heat_ = HeatScale::of(config.continuous_force_n);
        derating_ = Derating::of(config.derate_start, max_force_n - config.continuous_force_n);
      }
    }
  }

  /// The force `held_force_n` acted over the last `ticks` periods: heat or cool toward it.
  constexpr void advance(const Vec3<S>& held_force_n, std::int64_t ticks) noexcept {
    if (!enabled_ || ticks <= 0) return;
    if constexpr (kIsFixed<S>) {
      const Wide<S> target = heat_.target(detail::raw_squares(held_force_n));  // u = (|F| / F_c)^2
      // theta and u are >= 0, so theta - u is in range, and u + (theta - u) r^n with r^n in
      // [0, 1] (rounded never past theta - u) lies between u and theta: the same values
      // without the saturation tests.
      const Wide<S> difference = Wide<S>::from_raw(temperature_.raw() - target.raw());
      temperature_ = Wide<S>::from_raw(target.raw() + (difference * decay_over(ticks, target)).raw());
    } else {
      const Wide<S> target = Wide<S>::squared_norm(held_force_n * float_.inverse_continuous_n);  // u = (|F| / F_c)^2
      temperature_ = target + (temperature_ - target) * decay_over(ticks, target);
    }
  }

  /// The clamp the temperature allows now [N].
  constexpr S allowed_force() const noexcept {
    if (!enabled_) return max_force_n_;
    if constexpr (kIsFixed<S>) {
      // From theta in Q32.32, not rounded to Q16.16 first (a rounding, a saturating
      // product and a min were 40 cycles of the bound): theta - derate_start is exact (both >= 0);
      // past the span the clamp is F_c; below it the drop is (theta - derate_start) times the
      // slope (max - F_c) / (1 - derate_start), floored at configuration, so below 2^32 times
      // it is below (max - F_c) 2^32 and the drop, rounded, at most max - F_c: the clamp never
      // falls below F_c, and no step saturates.
      const std::int64_t above = temperature_.raw() - derating_.start;
      if (above <= 0) return max_force_n_;
      if (above >= derating_.span) return continuous_force_n_;
      const std::uint64_t drop = (static_cast<std::uint64_t>(above) * derating_.slope + (std::uint64_t{1} << 31)) >> 32;
      return S::from_raw(static_cast<typename S::Raw>(max_force_n_.raw() - static_cast<typename S::Raw>(drop)));
    } else {
      const S theta = temperature_.to_scalar();
      if (!(theta > float_.derate_start)) return max_force_n_;
      constexpr S kOne = scalar_cast<S>(1.0);
      const S fraction = min(kOne, (theta - float_.derate_start) * float_.derate_span_inverse);
      return max_force_n_ - (max_force_n_ - continuous_force_n_) * fraction;
    }
  }

  constexpr bool enabled() const noexcept { return enabled_; }
  /// theta: 0 cold, 1 rated.
  constexpr Wide<S> temperature() const noexcept { return temperature_; }
  /// Starts from a known temperature (tests; a warm restart).
  /// Below 0 (colder than ambient) it is taken as 0 in a Q format: advance() relies on theta >= 0.
  constexpr void set_temperature(Wide<S> theta) noexcept {
    if constexpr (kIsFixed<S>) {
      temperature_ = theta.raw() < 0 ? Wide<S>{} : theta;
    } else {
      temperature_ = theta;
    }
  }

  /// Gaps [periods] whose r^n the fixed-point build tabulates: the supervisor's default
  /// watchdog (30) and a little more.
  static constexpr std::int64_t kTabulatedGaps = 32;

 private:
  /// r^ticks (fixed point: from the table, or the conservative factor past it; see above).
  constexpr Decay<S> decay_over(std::int64_t ticks, Wide<S> target) const noexcept {
    if constexpr (kIsFixed<S>) {
      if (ticks <= kTabulatedGaps) [[likely]] {  // (GCC laid the usual case out of line and back)
        return decay_by_gap_[static_cast<std::size_t>(ticks - 1)];
      }
      return target > temperature_ ? Decay<S>{} : decay_by_gap_.back();
    } else {
      // One period, the usual case: r itself, no repeated squaring.
      return ticks == 1 ? decay_per_tick_ : decay_per_tick_.power(ticks);
    }
  }

  /// 1/F_c^2 = q 2^-32 2^(left - right) with q in [2^31, 2^32) (fixed point): u = |F|^2 / F_c^2
  /// from the raw squares of F [2^-32 N^2], their product with q rounded to 2^-32, then shifted
  /// (rounded again on a right shift): within 2^-31 of u relatively and 2^-32 absolutely.
  struct HeatScale {
    std::uint32_t mantissa = 0;  ///< q
    int left = 0;                ///< 1/F_c^2 >= 1: a shift up
    int right = 0;               ///< 1/F_c^2 < 1/2: a shift down
    std::uint64_t half = 0;      ///< 2^(right - 1), 0 without a right shift: its rounding
    std::uint64_t limit = 0;     ///< the largest squares whose u a Wide holds (past it: saturated)

    static constexpr HeatScale of([[maybe_unused]] double continuous_force_n) noexcept {
      HeatScale h;
      if constexpr (kIsFixed<S>) {  // (a body clang can check for a floating-point S too)
        double m = 1.0 / (continuous_force_n * continuous_force_n);  // then into [1/2, 1)
        double top = 0x1p63;               // 2^(63 - left): the Wide's range before the shift up
        while (m >= 1.0 && h.left < 62) {  // 32 halvings at most for a Q16.16 F_c (>= 2^-16 N)
          m *= 0.5;
          top *= 0.5;
          ++h.left;
        }
        while (m < 0.5 && h.right < 62) {  // 31 at most for a Q16.16 F_c (< 2^15 N)
          m *= 2.0;
          ++h.right;
        }
        const double q = m * 0x1p32;  // in [2^31, 2^32) but for an F_c no Q16.16 value has
        // q > 0: adding 1/2 and truncating rounds to nearest (the check warns for negatives).
        // NOLINTNEXTLINE(bugprone-incorrect-roundings)
        h.mantissa = q >= 0xFFFF'FFFFp0 ? 0xFFFF'FFFFU : static_cast<std::uint32_t>(q + 0.5);
        h.half = h.right > 0 ? std::uint64_t{1} << (h.right - 1) : 0U;
        // squares m < 2^(63 - left) keeps the product, rounded and shifted up, within the Wide's
        // range, and squares < 2^63 the product's high part; 2^-20 of margin for q's rounding and
        // the double's (u saturates at 2^31 (1 - 2^-20) at the earliest).
        const double fits = (top / m < 0x1p63 ? top / m : 0x1p63) * (1.0 - 0x1p-20);
        h.limit = static_cast<std::uint64_t>(fits);
      }
      return h;
    }
    /// u in Q32.32; past the range the largest value, with the flag (as squared_norm saturates).
    Wide<S> target([[maybe_unused]] std::uint64_t squares) const noexcept {
      if constexpr (!kIsFixed<S>) {
        return Wide<S>{};
      } else {
        // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's
        // static bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1
        // (Cortex-M3 TRM r2p1 table 3-1); no value changes.
        if (squares > limit) [[unlikely]] {
          S::note_saturation();
          return Wide<S>::from_raw(std::numeric_limits<std::int64_t>::max());
        }
        // squares q / 2^32 rounded, squares = h 2^32 + l: h q + (l q + 2^31) / 2^32 (squares <
        // 2^63, so h q < 2^63), then the shifts, which the limit keeps within the range.
        const std::uint64_t high = (squares >> 32) * mantissa;
        const std::uint64_t low = ((squares & 0xFFFF'FFFFU) * mantissa + (std::uint64_t{1} << 31)) >> 32;
        return Wide<S>::from_raw(static_cast<std::int64_t>((((high + low) << left) + half) >> right));
      }
    }
  };
  struct Unused {};
  /// The derating in Q32.32 (fixed point): where it starts and how wide it is in theta, and
  /// the clamp's drop per unit of theta [2^-16 N], floored.
  struct Derating {
    std::int64_t start = 0;
    std::int64_t span = 0;
    std::uint32_t slope = 0;

    static constexpr Derating of([[maybe_unused]] double derate_start, [[maybe_unused]] double range_n) noexcept {
      Derating d;
      if constexpr (kIsFixed<S>) {  // (a body clang can check for a floating-point S too)
        d.start = Wide<S>::from_double(derate_start).raw();
        d.span = Wide<S>::from_double(1.0 - derate_start).raw();
        const double slope = range_n / (1.0 - derate_start) * 65536.0;
        d.slope = slope >= 0xFFFF'FFFFp0 ? 0xFFFF'FFFFU : slope > 0.0 ? static_cast<std::uint32_t>(slope) : 0U;
      }
      return d;
    }
  };

  using GapTable =
      std::conditional_t<kIsFixed<S>, std::array<Decay<S>, static_cast<std::size_t>(kTabulatedGaps)>, Unused>;

  /// The floating-point builds' scaling and derating (as they were: their results unchanged).
  struct FloatForm {
    S inverse_continuous_n{};
    S derate_start{};
    S derate_span_inverse{};
  };

  bool enabled_;
  S max_force_n_;
  S continuous_force_n_;
  Decay<S> decay_per_tick_;
  [[no_unique_address]] std::conditional_t<kIsFixed<S>, Unused, FloatForm> float_{};
  [[no_unique_address]] GapTable decay_by_gap_{};
  [[no_unique_address]] std::conditional_t<kIsFixed<S>, HeatScale, Unused> heat_{};
  [[no_unique_address]] std::conditional_t<kIsFixed<S>, Derating, Unused> derating_{};
  Wide<S> temperature_{};
};

/// No thermal model: the clamp stays where it was configured.
template <Scalar S>
class NoThermal {
 public:
  constexpr NoThermal(const ThermalConfig&, double, double max_force_n) noexcept
      : max_force_n_(scalar_cast<S>(max_force_n)) {}
  constexpr void advance(const Vec3<S>&, std::int64_t) noexcept {}
  constexpr S allowed_force() const noexcept { return max_force_n_; }
  constexpr bool enabled() const noexcept { return false; }
  constexpr Wide<S> temperature() const noexcept { return {}; }

 private:
  S max_force_n_;
};

}  // namespace toonforce
