#pragma once
/// A first-order motor thermal model per device (after OpenHaptics' predicted
/// HD_MOTOR_TEMPERATURE, shared/reference/realtime-safety-stability.md §5). Copper losses grow
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
/// Cost per tick (issue 29, a bound by construction): in the fixed-point build no tick raises
/// r to a power. r^n for the gaps a running loop has (1, a late tick, a few missed ones, up to
/// kTabulatedGaps) is a table computed at configuration time; a longer gap (past the
/// supervisor's default watchdog of 30 periods, which latches a fault) takes a factor that
/// over-estimates the temperature: r^kTabulatedGaps when cooling (less cooling than
/// r^n), 0 when heating (all the way to the target u, above u + (theta - u) r^n). So the
/// derating is never weaker than the exact model's. The floating-point builds keep r^n by
/// repeated squaring (their results unchanged; no bound is taken of them).

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
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
        inverse_continuous_n_(scalar_cast<S>(enabled_ ? 1.0 / config.continuous_force_n : 0.0)),
        derate_start_(scalar_cast<S>(config.derate_start)),
        derate_span_inverse_(scalar_cast<S>(1.0 / (1.0 - config.derate_start))),
        derate_range_n_(max_force_n_ - continuous_force_n_),
        decay_per_tick_(Decay<S>::from_double(std::exp(-period_s / config.time_constant_s))) {
    if constexpr (kIsFixed<S>) {
      // r^n rounded once from the exact exponential (the first entry is decay_per_tick_).
      for (std::size_t i = 0; i < decay_by_gap_.size(); ++i) {
        const double ticks = static_cast<double>(i + 1);
        decay_by_gap_[i] = Decay<S>::from_double(std::exp(-ticks * period_s / config.time_constant_s));
      }
    }
  }

  /// The force `held_force_n` acted over the last `ticks` periods: heat or cool toward it.
  constexpr void advance(const Vec3<S>& held_force_n, std::int64_t ticks) noexcept {
    if (!enabled_ || ticks <= 0) return;
    const Vec3<S> relative = held_force_n * inverse_continuous_n_;
    const Wide<S> target = Wide<S>::squared_norm(relative);  // u = (|F| / F_c)^2
    if constexpr (kIsFixed<S>) {
      // theta and u are >= 0, so theta - u is in range, and u + (theta - u) r^n with r^n in
      // [0, 1] (rounded never past theta - u) lies between u and theta: the same values
      // without the saturation tests (issue 29).
      const Wide<S> difference = Wide<S>::from_raw(temperature_.raw() - target.raw());
      temperature_ = Wide<S>::from_raw(target.raw() + (difference * decay_over(ticks, target)).raw());
    } else {
      temperature_ = target + (temperature_ - target) * decay_over(ticks, target);
    }
  }

  /// The clamp the temperature allows now [N].
  constexpr S allowed_force() const noexcept {
    if (!enabled_) return max_force_n_;
    const S theta = temperature_.to_scalar();
    if (!(theta > derate_start_)) return max_force_n_;
    constexpr S kOne = scalar_cast<S>(1.0);
    if constexpr (kIsFixed<S>) {
      // The same steps, only the one that can leave the range saturated (issue 29): theta >
      // derate_start >= 0 (checked at configuration), so theta - derate_start is in range;
      // the fraction is in [0, 1], so the drop is at most max - F_c and max minus it at least F_c.
      const S above = S::from_raw(theta.raw() - derate_start_.raw());
      const S fraction = min(kOne, above * derate_span_inverse_);
      const S drop = S::from_product_in_range(typename S::Wide{derate_range_n_.raw()} * fraction.raw());
      return S::from_raw(max_force_n_.raw() - drop.raw());
    } else {
      const S fraction = min(kOne, (theta - derate_start_) * derate_span_inverse_);
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
      if (ticks <= kTabulatedGaps) return decay_by_gap_[static_cast<std::size_t>(ticks - 1)];
      return target > temperature_ ? Decay<S>{} : decay_by_gap_.back();
    } else {
      // One period, the usual case: r itself, no repeated squaring.
      return ticks == 1 ? decay_per_tick_ : decay_per_tick_.power(ticks);
    }
  }

  struct NoTable {};
  using GapTable = std::conditional_t<kIsFixed<S>, std::array<Decay<S>, static_cast<std::size_t>(kTabulatedGaps)>, NoTable>;

  bool enabled_;
  S max_force_n_;
  S continuous_force_n_;
  S inverse_continuous_n_;
  S derate_start_;
  S derate_span_inverse_;
  S derate_range_n_;  ///< max_force - F_c [N] (> 0 when enabled)
  Decay<S> decay_per_tick_;
  [[no_unique_address]] GapTable decay_by_gap_{};
  Wide<S> temperature_{};
};

/// No thermal model: the clamp stays where it was configured.
template <Scalar S>
class NoThermal {
 public:
  constexpr NoThermal(const ThermalConfig&, double, double max_force_n) noexcept : max_force_n_(scalar_cast<S>(max_force_n)) {}
  constexpr void advance(const Vec3<S>&, std::int64_t) noexcept {}
  constexpr S allowed_force() const noexcept { return max_force_n_; }
  constexpr bool enabled() const noexcept { return false; }
  constexpr Wide<S> temperature() const noexcept { return {}; }

 private:
  S max_force_n_;
};

}  // namespace toonforce
