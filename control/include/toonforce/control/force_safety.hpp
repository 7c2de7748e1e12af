// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The safety stage every force passes on its way out (spec effects.md §6), in this order:
///   1. non-finite guard: a non-finite input or scene force gives exactly 0, bypassing the rate
///      limit, and the previous output becomes 0 (the caller sets the fault and keeps states);
///   2. force-rate limit: |F_k - F_{k-1}| <= max_force_rate * dt, the step scaled down along
///      its direction, measured from the previous output;
///   3. force clamp, last: |F| <= max_force, direction kept. Clamping last keeps the limit hard
///      even when it drops (thermal derating).
/// Without limits (a scene with no [device] table) none applies.

#include <cstdint>

#include "toonforce/control/faults.hpp"
#include "toonforce/effects/tick.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// Limits in double as configured; ForceSafety converts them once.
struct ForceLimits {
  double max_force_n = 0.0;             ///< used when has_max_force
  double max_force_rate_n_per_s = 0.0;  ///< used when has_max_force_rate
  bool has_max_force = false;
  bool has_max_force_rate = false;
};

template <Scalar S>
class ForceSafety {
 public:
  struct Output {
    Vec3<S> force_n;
    std::uint8_t limits = 0;  ///< Limit bits
  };

  constexpr explicit ForceSafety(const ForceLimits& limits = {}) noexcept
      : max_force_n_(scalar_cast<S>(limits.max_force_n)),
        max_force_rate_n_per_s_(scalar_cast<S>(limits.max_force_rate_n_per_s)),
        has_max_force_(limits.has_max_force),
        has_max_force_rate_(limits.has_max_force_rate) {}

  /// Step 1: the output of a tick whose input or scene force is not finite.
  constexpr Output zero() noexcept {
    previous_n_ = Vec3<S>{};
    return {};
  }

  /// Steps 2 and 3 on a finite scene force; `rate_hz` is 1/dt since the previous output.
  constexpr Output limit(const Vec3<S>& scene_force_n, S rate_hz) noexcept {
    return limit_step(scene_force_n, has_max_force_rate_ ? max_force_rate_n_per_s_ / rate_hz : S{});
  }
  /// The same with the largest step, max_force_rate * dt, already known (a loop on a fixed
  /// period computes it once: max_step_for()).
  constexpr Output limit_step(const Vec3<S>& scene_force_n, S max_step) noexcept {
    Output out{scene_force_n, 0};
    // Each limit compares squares first: the norm (a square root) only when the limit bites.
    if constexpr (kIsFixed<S>) {  // exactly, in 64 bits, and no root (scaled_if_above says why)
      // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
      // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM
      // r2p1 table 3-1); no value changes.
      if (has_max_force_rate_) [[likely]] {
        if (const auto step = scaled_if_above(out.force_n - previous_n_, max_step)) {
          out.force_n = plus_in_range(previous_n_, *step);  // a scaled-down step toward the force
          out.limits = out.limits | Limit::kRateLimited;
        }
      }
      // (The hint: the dearer side in line, for the bound.)
      if (has_max_force_) [[likely]] {
        if (const auto clamped = scaled_if_above(out.force_n, max_force_n_)) {
          out.force_n = *clamped;
          out.limits = out.limits | Limit::kClamped;
        }
      }
    } else {  // the same tests, written out: the double loop's 600-instruction mean has no room
      if (has_max_force_rate_) {
        const Vec3<S> step = out.force_n - previous_n_;
        if (dot(step, step) > max_step * max_step) {
          const NormOf<S> step_size = norm_of(step);
          if (step_size.value > max_step) {
            out.force_n = previous_n_ + scale_to_norm(step, max_step, step_size);
            out.limits = out.limits | Limit::kRateLimited;
          }
        }
      }
      if (has_max_force_ && dot(out.force_n, out.force_n) > max_force_n_ * max_force_n_) {
        const NormOf<S> magnitude = norm_of(out.force_n);
        if (magnitude.value > max_force_n_) {
          out.force_n = scale_to_norm(out.force_n, max_force_n_, magnitude);
          out.limits = out.limits | Limit::kClamped;
        }
      }
    }
    previous_n_ = out.force_n;
    return out;
  }

  /// Lowers (or raises) the clamp at run time, e.g. for thermal derating; never above the
  /// configured one is the caller's business.
  constexpr void set_max_force(S max_force_n) noexcept {
    max_force_n_ = max_force_n;
    has_max_force_ = true;
  }
  constexpr S max_force() const noexcept { return max_force_n_; }
  /// max_force_rate * dt for a tick at `rate_hz` (0 without a rate limit).
  constexpr S max_step_for(S rate_hz) const noexcept {
    return has_max_force_rate_ ? max_force_rate_n_per_s_ / rate_hz : S{};
  }
  /// The same for a tick `dt_ns` long. Fixed point: from the integer time without its
  /// reciprocal (Q16.16 cannot hold 1/dt above 32,767 Hz: a 10 us tick's step would be the
  /// saturated rate's, three times too large), rounded down: the step never exceeds
  /// max_force_rate * dt. Floating point: through the rate, as the loop computes it.
  constexpr S max_step_for_ns(std::int64_t dt_ns) const noexcept {
    if constexpr (kIsFixed<S>) {
      return has_max_force_rate_ ? max_force_rate_n_per_s_.times_ns(dt_ns) : S{};
    } else {
      return max_step_for(scalar_cast<S>(1.0 / (static_cast<double>(dt_ns) / static_cast<double>(kNsPerS))));
    }
  }
  constexpr bool has_max_force() const noexcept { return has_max_force_; }
  constexpr const Vec3<S>& previous_output() const noexcept { return previous_n_; }

 private:
  S max_force_n_;
  S max_force_rate_n_per_s_;
  bool has_max_force_;
  bool has_max_force_rate_;
  Vec3<S> previous_n_{};
};

}  // namespace toonforce
