// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The handle as the loop sees it on one tick (spec effects.md §0): the device's position
/// converted to the scalar once, and its velocity, the device's own when it measures one, else
/// the one velocity estimator of the loop (control/velocity_estimator.hpp) when the scene or the
/// safety layer needs a velocity. The estimate is not committed until the tick counts (a
/// non-finite tick leaves the estimator as it was, spec §6.1), and 1/dt is taken since the last
/// tick that counted, so a dropped sample does not double the estimate.

#include <array>
#include <cstddef>
#include <cstdint>

#include "toonforce/control/clock.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

template <Scalar S>
struct Hip {
  Vec3<S> position_m;
  Vec3<S> velocity_m_per_s;      ///< zero when nothing needs a velocity
  S rate_hz{};                   ///< 1/dt since the last tick that counted [Hz]
  bool position_finite = false;  ///< the position can be used (the passivity observer needs only it)
  bool finite = false;           ///< position and any given velocity finite: the tick can count
  bool estimated = false;        ///< velocity_m_per_s is the estimator's, not yet committed
  bool stepped = false;          ///< the sensor took the step since the last counted tick (HipSensor::step)
};

/// The rate 1e9 / (g T) of g >= 1 periods of T ns in a Q format, exactly as
/// `S::from_ratio(kNsPerS, g * T)` rounds it, with one 32-bit division: with 2^F 1e9 = Q T + R
/// and b = 1 when 2R >= T, round(2^F 1e9 / (g T)) = floor((2Q + b + g) / (2g)) (R's share,
/// below one T, never reaches the next multiple of 2gT). Valid while 2Q + b fits 32 bits, that
/// is while one period's rate fits Q16.16 (T >= 30.5 us); a shorter period's rates do not.
template <Scalar S>
struct PeriodsRate {
  std::uint64_t twice_q_b = 0;  ///< 2Q + b
  bool fits = false;

  static constexpr PeriodsRate of(std::int64_t period_ns) noexcept {
    if (period_ns <= 0) return {};
    const auto t = static_cast<std::uint64_t>(period_ns);
    const std::uint64_t n = static_cast<std::uint64_t>(kNsPerS) << S::kFracBits;
    const std::uint64_t twice = 2 * (n / t) + (2 * (n % t) >= t ? 1U : 0U);
    return {twice, twice <= 0xFFFF'FFFFU};
  }
  /// The rate after `g` >= 1 periods (0 once it rounds to 0; saturated, with the flag, when
  /// the period is too short for the format).
  constexpr S after(std::int64_t g) const noexcept {
    if (!fits) [[unlikely]] {
      return S::from_wide(std::int64_t{1} << 32);  // past the range: the flag
    }
    if (static_cast<std::uint64_t>(g) > twice_q_b) [[unlikely]] {
      return S{};
    }
    const auto half_sum = static_cast<std::uint32_t>((twice_q_b + static_cast<std::uint64_t>(g)) >> 1);  // <= 2Q + b
    return S::from_wide(half_sum / static_cast<std::uint32_t>(g));  // floor(floor(M / 2) / g) = floor(M / 2g)
  }
};

/// `kMayEstimate` false compiles the estimator out (no scene effect, no safety stage needs it).
/// `kMayStamp` false: ticks come on the period only (no LoopStages::stamps), so in a Q format
/// 1/dt after a gap is PeriodsRate's (one 32-bit division), and the filter's gain a table's.
/// `kStep`: in a Q format, with a reading in S, the step since the last counted tick is taken
/// for the passivity stage too (step()), once for it and the estimator.
template <Scalar S, bool kMayEstimate, bool kMayStamp = true, bool kStep = false>
class HipSensor {
  /// A late tick's filter gain comes from a table (gain_after).
  static constexpr bool kGainTable = kIsFixed<S> && !kMayStamp && kMayEstimate;

 public:
  /// `period_s` > 0: ticks come on this period, and 1/dt and the filter's gain for one period
  /// are computed once, here.
  constexpr HipSensor(double velocity_cutoff_hz, bool estimate, double period_s) noexcept
      : estimator_(velocity_cutoff_hz),
        estimate_(kMayEstimate && estimate),
        period_rate_hz_(scalar_cast<S>(1.0 / period_s)),
        period_gain_(estimator_.gain(period_rate_hz_)),
        periods_rate_(periods_rate_of(period_s)) {
    if constexpr (kGainTable) {
      for (std::size_t i = 0; i < gains_.size(); ++i) {
        gains_[i] = estimator_.gain(periods_rate_.after(static_cast<std::int64_t>(i + 1)));
      }
    }
  }

  /// Late ticks (Q formats on the period's ticks) whose filter gain is tabulated: the
  /// supervisor's default watchdog (30 periods) and a little more, as the thermal model's decay.
  static constexpr std::int64_t kTabulatedGaps = 32;

  /// `reading` in double, or already in S (a device that reads in the loop's scalar: a
  /// fixed-point target's, tools/mcu). With kStep, a Q format and a reading in S, it also takes
  /// the step since the last counted tick for the passivity stage (step()).
  template <class T>
  Hip<S> sense(const BasicDeviceReading<T>& reading, const TickTime& time) const noexcept {
    Hip<S> h;
    h.position_finite = is_finite(reading.position_m);
    h.finite = h.position_finite && (!reading.has_velocity || is_finite(reading.velocity_m_per_s));
    if (!h.position_finite) return h;
    h.position_m = in_scalar(reading.position_m);
    // One period since the last tick that counted, the usual case: the rate computed once.
    const std::int64_t since = has_commit_ ? time.now.tick - last_commit_.tick : time.gap;  // ticks
    bool one_period;
    if constexpr (kIsFixed<S> && !kMayStamp) {  // the period's ticks only: from the count
      one_period = since == 1;
      h.rate_hz = one_period ? period_rate_hz_ : periods_rate_.after(since);
    } else if constexpr (kIsFixed<S>) {  // integer time (control/clock.hpp): 1e9 / ns, no floating point
      one_period = since == 1 && time.period_ns > 0;
      h.rate_hz =
          one_period ? period_rate_hz_ : S::from_ratio(kNsPerS, has_commit_ ? time.ns_since(last_commit_) : time.dt_ns);
    } else {
      one_period = since == 1 && time.period_s > 0.0;
      h.rate_hz = one_period ? period_rate_hz_
                             : scalar_cast<S>(1.0 / (has_commit_ ? time.seconds_since(last_commit_) : time.dt_s()));
    }
    // The step since the last tick that counted, once for the estimator and, in a Q loop that
    // reads in S (every tick with a position counts there: a Q value is finite), the passivity
    // observer (kStep), which took the same difference on its own.
    const bool estimating = kMayEstimate && estimate_ && !reading.has_velocity;
    if constexpr (kStep) {
      static_assert(kIsFixed<S>);
      // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
      // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM
      // r2p1 table 3-1); no value changes.
      if (has_commit_ && (std::is_same_v<T, S> || estimating)) [[likely]] {
        step_m_ = h.position_m - position_m_;
        h.stepped = true;
      }
      estimate_into(h, reading.has_velocity, reading.velocity_m_per_s, step_m_, one_period, since);
    } else {
      Vec3<S> step;
      if (has_commit_ && estimating) {
        step = h.position_m - position_m_;
        h.stepped = true;
      }
      estimate_into(h, reading.has_velocity, reading.velocity_m_per_s, step, one_period, since);
    }
    return h;
  }

  /// The tick counted: its estimate becomes the estimator's state. The position, velocity and
  /// time of the last tick that counted are kept once, here (the estimator keeps the velocity
  /// it estimated): the step of the next tick is taken from them, and the loop's telemetry
  /// reads them (SceneStage::describe, the frame), where the scene stage and the loop used to
  /// copy them again on every tick (22-40 cycles of the bound for the position and
  /// time).
  constexpr void commit(const Hip<S>& h, const TickTime& time) noexcept {
    position_m_ = h.position_m;
    if constexpr (kMayEstimate) {
      if (h.estimated) {
        estimator_.commit_velocity(h.velocity_m_per_s);
      } else {
        velocity_m_per_s_ = h.velocity_m_per_s;
      }
      estimated_ = h.estimated;
    } else {
      velocity_m_per_s_ = h.velocity_m_per_s;
    }
    last_commit_ = time.now;
    has_commit_ = true;
  }
  /// kStep: the last sense()'s step since the last counted tick, when it took one (Hip::stepped).
  /// In a Q format every tick with a position counts, so that is also the step since the last
  /// good position, the passivity observer's. (Kept here, not in the Hip: a Hip that large was
  /// cleared by a call to memset, a loop the tick's bound refuses.)
  constexpr const Vec3<S>& step() const noexcept { return step_m_; }
  /// The position of the last tick that counted (zero before the first).
  constexpr const Vec3<S>& committed_position() const noexcept { return position_m_; }
  /// The velocity the last tick that counted saw (zero before the first, and when nothing
  /// needed one).
  constexpr const Vec3<S>& committed_velocity() const noexcept {
    if constexpr (kMayEstimate) {
      if (estimated_) return estimator_.velocity();
    }
    return velocity_m_per_s_;
  }
  /// The time of the last tick that counted (zero before the first).
  constexpr Instant committed_at() const noexcept { return last_commit_; }

 private:
  /// The velocity into `h`: the device's, else the estimator's from `step` when estimating.
  template <class T>
  void estimate_into(Hip<S>& h, bool has_velocity, const Vec3<T>& device_velocity, const Vec3<S>& step, bool one_period,
                     std::int64_t since) const noexcept {
    if (has_velocity) {
      h.velocity_m_per_s = in_scalar(device_velocity);
    } else if constexpr (kMayEstimate) {
      if (estimate_) {
        const S gain = kGainTable ? (one_period ? period_gain_ : gain_after(since))
                                  : (one_period ? period_gain_ : estimator_.gain(h.rate_hz));
        h.velocity_m_per_s = estimator_.estimate_step(step, h.rate_hz, gain);  // started: stepped
        h.estimated = true;
      }
    }
  }

  static constexpr auto periods_rate_of(double period_s) noexcept {
    if constexpr (kIsFixed<S> && !kMayStamp) {
      return PeriodsRate<S>::of(ns_from_seconds(period_s));
    } else {
      return NoPeriodsRate{};
    }
  }
  /// Q formats on the period's ticks: the gain after `since` periods from the table
  /// (bit for bit what estimator_.gain(periods_rate_.after(since)) gives: no reciprocal in the
  /// tick); past it 1, the gain's limit as the gap grows (the backward difference
  /// over the gap itself; the exact gain is 0.91 at 33 periods of 1 ms with the default 50 Hz
  /// cutoff and nearer 1 after longer gaps, which the default watchdog has faulted the loop for).
  S gain_after([[maybe_unused]] std::int64_t since) const noexcept {
    if constexpr (kGainTable) {                              // (a body clang can check in every instantiation)
      const auto k = static_cast<std::uint64_t>(since - 1);  // since >= 1: ticks only move on
      return k < gains_.size() ? gains_[static_cast<std::size_t>(k)] : scalar_cast<S>(1.0);
    } else {
      return period_gain_;
    }
  }

  template <class T>
  static constexpr Vec3<S> in_scalar(const Vec3<T>& v) noexcept {
    if constexpr (std::is_same_v<T, S>) {
      return v;
    } else {
      return vec_cast<S>(v);
    }
  }

  [[no_unique_address]] std::conditional_t<kMayEstimate, VelocityEstimator<S>, NoVelocityEstimator<S>> estimator_;
  bool estimate_;
  S period_rate_hz_;  ///< 1/T
  S period_gain_;     ///< the filter's gain at 1/T
  struct NoPeriodsRate {};
  [[no_unique_address]] std::conditional_t<kIsFixed<S> && !kMayStamp, PeriodsRate<S>, NoPeriodsRate> periods_rate_;
  [[no_unique_address]] std::conditional_t<kGainTable, std::array<S, static_cast<std::size_t>(kTabulatedGaps)>,
                                           NoPeriodsRate>
      gains_{};
  bool has_commit_ = false;
  bool estimated_ = false;  ///< the last tick that counted was estimated: the estimator holds its velocity
  Instant last_commit_{};
  mutable Vec3<S> step_m_{};    ///< kStep: sense()'s step (a tick's scratch, not state)
  Vec3<S> position_m_{};        ///< the last tick that counted's position
  Vec3<S> velocity_m_per_s_{};  ///< and its velocity when not estimated (the device's, or zero)
};

}  // namespace toonforce
