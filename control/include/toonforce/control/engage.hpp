// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Engage and soft start, the first stage of the safety chain (spec effects.md §6 "The servo
/// loop adds more"): after start, enable and re-arm, forces come on only once the scene force
/// where the handle is falls below `engage_force` (CHAI3D's 0.2 N start-up rule: enabling inside
/// a wall never throws the handle); then a linear ramp from 0 to full force over `soft_start`
/// seconds. A fault that cut the force ramps it again; a loop still waiting keeps waiting.
/// Time is integer ticks (spec §0): the gain at tick k is (k - k_start) T / soft_start.
/// `NoEngage` is full force at once (replay: effects.md §6 only).

#include <cstdint>

#include "toonforce/control/supervisor.hpp"
#include "toonforce/effects/tick.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

struct EngageConfig {
  double engage_force_n = 0.2;  ///< [N] > 0
  double soft_start_s = 1.0;    ///< [s] >= 0; 0: no ramp
  double period_s = 1e-3;       ///< [s] the servo period
};

template <Scalar S>
class Engage {
 public:
  constexpr explicit Engage(const EngageConfig& config) noexcept
      : Engage(config, ns_from_seconds(config.period_s), ns_from_seconds(config.soft_start_s)) {}

  /// The gate opened again: wait for the scene force to be small before any force flows.
  void reset() noexcept { state_ = LoopState::kEngaging; }
  /// The force was cut by a fault: if it was (coming) on, ramp again from tick `from`.
  void restart(std::int64_t from) noexcept {
    if (state_ == LoopState::kRamping || state_ == LoopState::kActive) start(from);
  }

  /// The gain for tick k given the scene force there: 0 while waiting to engage (engaging()
  /// then says so), the ramp while ramping, 1 once active.
  S gain(const Vec3<S>& scene_force_n, std::int64_t k) noexcept {
    // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
    // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM r2p1
    // table 3-1); no value changes.
    if (state_ == LoopState::kEngaging) [[likely]] {
      // By the squares (exact in a Q format): no square root on the tick.
      // (The hint: the dearer side in line, for the bound.)
      if (!norm_below(scene_force_n, engage_force_squared_)) [[unlikely]]
        return S{};
      start(k);
    }
    constexpr S kOne = scalar_cast<S>(1.0);
    if (state_ != LoopState::kRamping) return kOne;
    if constexpr (kIsFixed<S>) {  // integer nanoseconds, no floating point (control/clock.hpp)
      // (k - start) T < soft_start as a count of ticks (ramp_ticks_): no 64-bit product.
      const std::int64_t ticks = k - ramp_start_;
      // (The hint: the dearer side in line, for the bound.)
      if (!(ticks < ramp_ticks_)) [[unlikely]] {
        state_ = LoopState::kActive;
        return kOne;
      }
      // (k - start) T / soft_start as (k - start) times a 32-bit fraction per tick, rounded
      // once: no division on the tick. The fraction is within 2^-33 of T /
      // soft_start, so the gain is within (k - start) 2^-17 LSB of the exact quotient (under
      // 0.01 LSB for a 1 s ramp at 1 kHz); elapsed < soft_start keeps the product below 2^33,
      // and ticks < ramp_ticks_ <= 2^32 lets it be one 32x32 product.
      const auto product = std::uint64_t{static_cast<std::uint32_t>(ticks)} * static_cast<std::uint32_t>(ramp_step_);
      const auto ramp =
          static_cast<typename S::Raw>((product + (std::uint64_t{1} << (31 - S::kFracBits))) >> (32 - S::kFracBits));
      // At most 1 (the loop scales by it without a saturation test, times_in_range): a ramp of
      // more than 2^16 ticks may round past it by the step's rounding.
      return ramp < kOne.raw() ? S::from_raw(ramp) : kOne;
    } else {
      // Time from integer ticks, in double, converted once (spec §0).
      const double elapsed_s = static_cast<double>(k - ramp_start_) * period_s_;
      if (!(elapsed_s < soft_start_s_)) {
        state_ = LoopState::kActive;
        return kOne;
      }
      return scalar_cast<S>(elapsed_s / soft_start_s_);
    }
  }

  bool engaging() const noexcept { return state_ == LoopState::kEngaging; }
  LoopState state() const noexcept { return state_; }

 private:
  /// The period and the soft start in integer nanoseconds, converted once.
  constexpr Engage(const EngageConfig& config, std::int64_t period_ns, std::int64_t soft_start_ns) noexcept
      : engage_force_squared_(squared_limit<S>(config.engage_force_n)),
        soft_start_s_(config.soft_start_s),
        period_s_(config.period_s),
        ramp_step_(ramp_step_of(period_ns, soft_start_ns)),
        ramp_ticks_(ramp_ticks_of(period_ns, soft_start_ns)) {}

  /// round(2^32 T / soft_start) when T < soft_start (a ramp of more than one tick; one of one
  /// tick or none never reaches the product). Start-up only: one 64-bit division.
  static constexpr std::uint64_t ramp_step_of(std::int64_t period_ns, std::int64_t soft_start_ns) noexcept {
    if (period_ns <= 0 || soft_start_ns <= period_ns) return 0;
    const auto t = static_cast<std::uint64_t>(period_ns);
    const auto d = static_cast<std::uint64_t>(soft_start_ns);
    if (t >= (std::uint64_t{1} << 31))
      return ((t << 1) / (d >> 31) + 1) >> 1;  // periods over 2 s: 2^32 t / d from d's top bits
    return ((t << 32) + d / 2) / d;
  }

  /// The ticks of the ramp: the least n with n T >= soft_start (so (k - start) T < soft_start
  /// is k - start < n exactly), at most 2^32 (a ramp of more periods, 49 days at 1 kHz, ends
  /// there, at a gain of 2^32 T / soft_start). Start-up only.
  static constexpr std::int64_t ramp_ticks_of(std::int64_t period_ns, std::int64_t soft_start_ns) noexcept {
    if (soft_start_ns <= 0) return 0;
    if (period_ns <= 0) return std::int64_t{1} << 32;
    const std::int64_t n = soft_start_ns / period_ns + (soft_start_ns % period_ns != 0 ? 1 : 0);
    return n < (std::int64_t{1} << 32) ? n : std::int64_t{1} << 32;
  }

  void start(std::int64_t from) noexcept {
    state_ = LoopState::kRamping;
    ramp_start_ = from;
  }

  SquaredLimit<S> engage_force_squared_;  ///< [N^2]
  double soft_start_s_;
  double period_s_;
  // A fixed-point S's ramp, from the times in integer nanoseconds (control/clock.hpp).
  std::uint64_t ramp_step_;  ///< a fixed-point S's gain per tick: round(2^32 T / soft_start), below 2^32
  std::int64_t ramp_ticks_;  ///< a fixed-point S's ramp in ticks (ramp_ticks_of)
  LoopState state_ = LoopState::kEngaging;
  std::int64_t ramp_start_ = 0;
};

/// Full force at once, always.
template <Scalar S>
class NoEngage {
 public:
  constexpr explicit NoEngage(const EngageConfig&) noexcept {}
  void reset() noexcept {}
  void restart(std::int64_t) noexcept {}
  S gain(const Vec3<S>&, std::int64_t) noexcept { return scalar_cast<S>(1.0); }
  bool engaging() const noexcept { return false; }
  LoopState state() const noexcept { return LoopState::kActive; }
};

}  // namespace toonforce
