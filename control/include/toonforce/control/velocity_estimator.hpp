// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Velocity estimator for devices and inputs that give no velocity (spec effects.md §0): a
/// first-order low-pass of the backward difference,
///   v_k = v_{k-1} + a ((x_k - x_{k-1})/dt - v_{k-1}),  a = dt / (dt + 1/(2 pi f_c)),
/// written with the rate 1/dt (see TickInput::rate_hz): a = 1 / (1 + rate / (2 pi f_c)).
/// The first update gives 0.

#include "toonforce/math/vec3.hpp"

namespace toonforce {

template <Scalar S>
class VelocityEstimator {
 public:
  static constexpr double kDefaultCutoffHz = 50.0;

  constexpr explicit VelocityEstimator(double cutoff_hz = kDefaultCutoffHz) noexcept
      : time_constant_s_(scalar_cast<S>(1.0 / (2.0 * 3.14159265358979323846 * cutoff_hz))) {}

  /// The estimate at this tick, from the position and 1/dt since the last committed update.
  /// Does not change the estimator: `commit` does, once the tick is known to be good.
  constexpr Vec3<S> estimate(const Vec3<S>& position_m, S rate_hz) const noexcept {
    return estimate(position_m, rate_hz, gain(rate_hz));
  }
  /// The same with the filter's gain a for this rate already known (gain(rate_hz)): a loop on a
  /// fixed period computes it once.
  constexpr Vec3<S> estimate(const Vec3<S>& position_m, S rate_hz, S a) const noexcept {
    // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
    // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM r2p1
    // table 3-1); no value changes.
    if (!started_) [[unlikely]]
      return velocity_;
    if constexpr (kIsFixed<S>) {
      return filtered(position_m - previous_m_, rate_hz, a);
    } else {
      return velocity_ + ((position_m - previous_m_) * rate_hz - velocity_) * a;
    }
  }
  /// The same from the step dx = x_k - x_{k-1} already taken (once started: a commit came
  /// before, so there was a last position), for an owner that keeps the positions (HipSensor,
  /// which takes the step once for this and the passivity stage) and commits the velocity
  /// alone (commit_velocity).
  constexpr Vec3<S> estimate_step(const Vec3<S>& dx, S rate_hz, S a) const noexcept {
    // (The hint: the dearer side in line, for the bound.)
    if (!started_) [[unlikely]]
      return velocity_;
    if constexpr (kIsFixed<S>) {
      return filtered(dx, rate_hz, a);
    } else {
      return velocity_ + (dx * rate_hz - velocity_) * a;
    }
  }
  /// a = 1 / (1 + rate / (2 pi f_c)), for a rate >= 0 (a denominator of at least 1: in a Q
  /// format its reciprocal is one 32-bit division).
  constexpr S gain(S rate_hz) const noexcept {
    constexpr S kOne = scalar_cast<S>(1.0);
    if constexpr (kIsFixed<S>) {
      return S::reciprocal_of_at_least_one(kOne + rate_hz * time_constant_s_);
    } else {
      return kOne / (kOne + rate_hz * time_constant_s_);
    }
  }
  /// Makes `estimate`'s result the estimator's state.
  constexpr void commit(const Vec3<S>& position_m, const Vec3<S>& velocity_m_per_s) noexcept {
    started_ = true;
    previous_m_ = position_m;
    velocity_ = velocity_m_per_s;
  }
  /// Makes estimate_step's result the estimator's state (its owner keeps the position).
  constexpr void commit_velocity(const Vec3<S>& velocity_m_per_s) noexcept {
    started_ = true;
    velocity_ = velocity_m_per_s;
  }
  /// estimate + commit.
  constexpr Vec3<S> update(const Vec3<S>& position_m, S rate_hz) noexcept {
    const Vec3<S> v = estimate(position_m, rate_hz);
    commit(position_m, v);
    return v;
  }
  constexpr const Vec3<S>& velocity() const noexcept { return velocity_; }

 private:
  /// Q formats: the same filter as v (1 - a) + dx (rate a): per component two raw products
  /// summed exactly and rounded once, where the floating-point form rounds and saturates five
  /// times (a third of the operations). |dx rate a| <= 2^62 since rate a <= rate, and
  /// |v (1 - a)| < 2^47, so the sum stays in 64 bits. With a in (0, 1] (gain()), 1 - a is in
  /// [0, 1) and |rate a| <= |rate|: neither needs the saturation test.
  constexpr Vec3<S> filtered([[maybe_unused]] const Vec3<S>& dx, [[maybe_unused]] S rate_hz,
                             [[maybe_unused]] S a) const noexcept {
    if constexpr (kIsFixed<S>) {  // (a body clang can check in every instantiation)
      using W = typename S::Wide;
      constexpr S kOne = scalar_cast<S>(1.0);
      const S keep = S::from_raw(kOne.raw() - a.raw());
      const S gain = S::from_product_in_range(W{rate_hz.raw()} * a.raw());
      const auto one = [keep, gain](S d, S v) {
        return S::from_product(W{d.raw()} * gain.raw() + W{v.raw()} * keep.raw());
      };
      return {one(dx.x, velocity_.x), one(dx.y, velocity_.y), one(dx.z, velocity_.z)};
    } else {
      return velocity_;
    }
  }

  S time_constant_s_;  ///< 1/(2 pi f_c) [s]
  Vec3<S> previous_m_{};
  Vec3<S> velocity_{};
  bool started_ = false;
};

/// Stands in for the estimator in scenes that need no velocity: no state, no work.
template <Scalar S>
struct NoVelocityEstimator {
  constexpr explicit NoVelocityEstimator(double = 0.0) noexcept {}
  constexpr Vec3<S> estimate(const Vec3<S>&, S) const noexcept { return {}; }
  constexpr Vec3<S> estimate(const Vec3<S>&, S, S) const noexcept { return {}; }
  constexpr S gain(S) const noexcept { return {}; }
  constexpr void commit(const Vec3<S>&, const Vec3<S>&) noexcept {}
  constexpr Vec3<S> estimate_step(const Vec3<S>&, S, S) const noexcept { return {}; }
  constexpr void commit_velocity(const Vec3<S>&) noexcept {}
  constexpr Vec3<S> update(const Vec3<S>&, S) noexcept { return {}; }
};

}  // namespace toonforce
