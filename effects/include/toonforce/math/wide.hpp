// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Accumulators for the safety layer's slow states and energies: the thermal model's
/// temperature and the passivity observer's energies change by a few parts in 10^5 per tick,
/// below the resolution of Q16.16 (spec effects.md §7: accumulators use 64-bit intermediates).
///
/// `Wide<S>` is a double for the floating-point scalars and a Q32.32 integer (int64, units of
/// 2^-32) for the fixed-point one, so the firmware build stays integer-only here: the work
/// F.dx of two Q16.16 vectors is exact in Q32.32 (the raw products are already in 2^-32 units),
/// and an energy or a temperature accumulates over hours without rounding drift (range
/// +-2^31: 600 years of 1 W). `Decay<S>` is a factor r in [0, 1) (Q0.32 in the fixed build)
/// with r^n by repeated squaring, for a first-order filter over n ticks (skipped ticks
/// included) in log2(n) multiplications.
///
/// Scaling and overflow (fixed build): sums saturate at +-2^31 and set the sticky saturation
/// flag (reported as Fault::kFixedSaturation); products with a Decay round to nearest.

#include <cmath>
#include <compare>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "toonforce/math/loop_bound.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

template <Scalar S>
class Decay;

template <Scalar S>
class Wide {
 public:
  constexpr Wide() noexcept = default;

  /// From a configuration value (start-up).
  static constexpr Wide from_double(double value) noexcept {
    Wide w;
    if constexpr (kIsFixed<S>) {
      const double scaled = value * kOne;
      if (!(scaled < 9.2e18 && scaled > -9.2e18)) {  // also NaN
        S::note_saturation();
        w.rep_ = scaled > 0 ? kMax : -kMax;
      } else {
        w.rep_ = std::llround(scaled);
      }
    } else {
      w.rep_ = value;
    }
    return w;
  }
  static constexpr Wide from_scalar(S value) noexcept {
    Wide w;
    if constexpr (kIsFixed<S>) {
      w.rep_ = static_cast<std::int64_t>(value.raw()) * (std::int64_t{1} << (32 - S::kFracBits));
    } else {
      w.rep_ = static_cast<double>(value);
    }
    return w;
  }
  /// Raw Q32.32 counts, in and out (fixed build): for tests of the saturating sums (the
  /// images check theirs against the compiler's on the target, tools/mcu/firmware/main.cpp).
  /// (The casts are no-ops where these exist; they keep the bodies well-formed for a compiler
  /// that checks them in an explicit instantiation of a floating-point Wide, clang does.)
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  static constexpr Wide from_raw(std::int64_t counts) noexcept
    requires(kIsFixed<S>)
  {
    return make(static_cast<Rep>(counts));
  }
  // clang-format on
  // clang-format off
  constexpr std::int64_t raw() const noexcept
    requires(kIsFixed<S>)
  {
    return static_cast<std::int64_t>(rep_);
  }
  // clang-format on
  /// a.b, exact in the fixed build (each raw product is in units of 2^-32 already).
  static constexpr Wide dot(const Vec3<S>& a, const Vec3<S>& b) noexcept {
    Wide w;
    if constexpr (kIsFixed<S>) {
      static_assert(S::kFracBits == 16, "Q32.32 holds products of Q16.16 values");
      const auto product = [](S p, S q) { return static_cast<std::int64_t>(p.raw()) * q.raw(); };
      w.rep_ = saturating_add(saturating_add(product(a.x, b.x), product(a.y, b.y)), product(a.z, b.z));
    } else {
      w.rep_ = static_cast<double>(a.x) * static_cast<double>(b.x) +
               static_cast<double>(a.y) * static_cast<double>(b.y) +
               static_cast<double>(a.z) * static_cast<double>(b.z);
    }
    return w;
  }

  /// v.v, exact in the fixed build like dot(v, v), from the raw squares summed unsigned (each
  /// below 2^62, the three below 2^64): the same value and flag as dot(v, v), which saturates
  /// at +2^63 exactly when this sum passes it, with fewer steps (no signed overflow tests).
  static constexpr Wide squared_norm(const Vec3<S>& v) noexcept {
    if constexpr (kIsFixed<S>) {
      static_assert(S::kFracBits == 16, "Q32.32 holds products of Q16.16 values");
      const std::uint64_t squares = detail::raw_squares(v);
      if (squares > static_cast<std::uint64_t>(kMax)) {
        if (!std::is_constant_evaluated()) S::note_saturation();
        return make(kMax);
      }
      return make(static_cast<std::int64_t>(squares));
    } else {
      return dot(v, v);
    }
  }

  constexpr double to_double() const noexcept {
    if constexpr (kIsFixed<S>) {
      return static_cast<double>(rep_) / kOne;
    } else {
      return rep_;
    }
  }
  /// Rounded to nearest; saturates (with the flag) outside S's range.
  constexpr S to_scalar() const noexcept {
    if constexpr (kIsFixed<S>) {
      return S::from_wide(S::round_shift(rep_, 32 - S::kFracBits));
    } else {
      return static_cast<S>(rep_);
    }
  }

  friend constexpr Wide operator+(Wide a, Wide b) noexcept {
    if constexpr (kIsFixed<S>) {
      return make(saturating_add(a.rep_, b.rep_));
    } else {
      return make(a.rep_ + b.rep_);
    }
  }
  friend constexpr Wide operator-(Wide a, Wide b) noexcept {
    if constexpr (kIsFixed<S>) {
      return make(saturating_add(a.rep_, -b.rep_));  // |raw| <= kMax, so -raw cannot overflow
    } else {
      return make(a.rep_ - b.rep_);
    }
  }
  /// This value times `fraction` in [0, 1], rounded once in the fixed build (to nearest, half
  /// up): with the raw d = dh 2^32 + dl and q = fraction's raw (0..2^16), d q / 2^16 is
  /// dh q 2^16 + (dl q + 2^15) / 2^16, two 32x32 products; |dh q| <= 2^47 and dl q + 2^15 <
  /// 2^49, so nothing overflows, and |result| <= |d| cannot saturate. (A vector scaled by the
  /// fraction first rounds each component to 2^-16 instead, and takes three Q16.16 products.)
  constexpr Wide times_fraction(S fraction) const noexcept {
    if constexpr (kIsFixed<S>) {
      static_assert(S::kFracBits == 16, "a fraction's raw is in 2^-16 units");
      // dh: the high word as a signed one (the floor of d / 2^32); taken by an unsigned shift, as
      // GCC then multiplies it with SMULL (from an arithmetic shift it made three multiplies).
      const auto dh = static_cast<std::int32_t>(static_cast<std::uint64_t>(rep_) >> 32);
      const auto dl = static_cast<std::uint32_t>(rep_);
      const std::int32_t q = fraction.raw();
      const auto low = (std::uint64_t{dl} * static_cast<std::uint32_t>(q) + (std::uint64_t{1} << 15)) >> 16;
      const std::int64_t high = std::int64_t{dh} * q;
      return make(static_cast<std::int64_t>(static_cast<std::uint64_t>(high) << 16) + static_cast<std::int64_t>(low));
    } else {
      return make(rep_ * static_cast<double>(fraction));
    }
  }

  constexpr Wide& operator+=(Wide o) noexcept { return *this = *this + o; }
  constexpr Wide& operator-=(Wide o) noexcept { return *this = *this - o; }
  friend constexpr Wide operator*(Wide a, Decay<S> r) noexcept { return r.apply(a); }
  // NOLINTNEXTLINE(modernize-use-nullptr): a false positive, as for Fixed's <=> (fixed.hpp)
  friend constexpr auto operator<=>(const Wide&, const Wide&) noexcept = default;
  friend constexpr bool operator==(const Wide&, const Wide&) noexcept = default;

 private:
  friend class Decay<S>;
  static constexpr double kOne = 4294967296.0;  // 2^32
  static constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();

  /// The representation: Q32.32 raw counts (fixed build) or the value (floating builds).
  using Rep = std::conditional_t<kIsFixed<S>, std::int64_t, double>;
  static constexpr Wide make(Rep r) noexcept {
    Wide w;
    w.rep_ = r;
    return w;
  }
  [[gnu::always_inline]] static constexpr std::int64_t saturating_add(std::int64_t a, std::int64_t b) noexcept {
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
    // Single-path on the images, as Fixed's operators (math/fixed.hpp says why).
    if constexpr (kIsFixed<S>) {
      if (!std::is_constant_evaluated() && !(__builtin_constant_p(a) && __builtin_constant_p(b))) {
        return detail::saturating_add_doublewords(a, b);
      }
    }
#endif
    std::int64_t sum = 0;
    if (__builtin_add_overflow(a, b, &sum)) {
      if constexpr (kIsFixed<S>) {
        if (!std::is_constant_evaluated()) S::note_saturation();
      }
      return b > 0 ? kMax : -kMax;
    }
    return sum;
  }

  Rep rep_{};
};

/// A per-tick factor r in [0, 1): `Wide * Decay`, and `power(n)` = r^n.
template <Scalar S>
class Decay {
 public:
  constexpr Decay() noexcept = default;
  /// From a configuration value in [0, 1] (start-up); 1 saturates to the largest factor < 1.
  static constexpr Decay from_double(double r) noexcept {
    Decay d;
    if constexpr (kIsFixed<S>) {
      const double scaled = std::round(r * 4294967296.0);
      d.q_ = scaled <= 0.0 ? 0U : scaled >= 4294967295.0 ? 0xFFFFFFFFU : static_cast<std::uint32_t>(scaled);
    } else {
      d.q_ = r;
    }
    return d;
  }
  /// r^n for n >= 0 (r^0 = 1 is represented exactly as "no decay").
  constexpr Decay power(std::int64_t n) const noexcept {
    Decay result = one();
    Decay base = *this;
    while (n > 0) {
      TOONFORCE_LOOP_BOUND(std::numeric_limits<std::int64_t>::digits);  // n loses a bit each round
      if ((n & 1) != 0) result = result.times(base);
      n >>= 1;
      if (n > 0) base = base.times(base);
    }
    return result;
  }
  constexpr double to_double() const noexcept {
    if constexpr (kIsFixed<S>) {
      return is_one_ ? 1.0 : static_cast<double>(q_) / 4294967296.0;
    } else {
      return q_;
    }
  }

  constexpr Wide<S> apply(Wide<S> w) const noexcept {
    if constexpr (kIsFixed<S>) {
      // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
      // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM
      // r2p1 table 3-1); no value changes.
      if (is_one_) [[unlikely]]
        return w;
      // (d * q) / 2^32 rounded, with d = dh 2^32 + dl: dh q + (dl q + 2^31) / 2^32. Neither
      // part overflows: |dh q| < 2^63 and dl q + 2^31 < 2^64.
      const std::int64_t d = w.rep_;
      const std::int64_t dh = d >> 32;  // arithmetic shift (C++20): floor
      const auto dl = static_cast<std::uint64_t>(d) & 0xFFFFFFFFULL;
      const auto low = (dl * q_ + (std::uint64_t{1} << 31)) >> 32;
      return Wide<S>::make(dh * static_cast<std::int64_t>(q_) + static_cast<std::int64_t>(low));
    } else {
      return Wide<S>::make(w.rep_ * q_);
    }
  }

 private:
  static constexpr Decay one() noexcept {
    Decay d;
    if constexpr (kIsFixed<S>) {
      d.is_one_ = true;
    } else {
      d.q_ = 1.0;
    }
    return d;
  }
  constexpr Decay times(Decay o) const noexcept {
    if constexpr (kIsFixed<S>) {
      if (is_one_) return o;
      if (o.is_one_) return *this;
      Decay d;
      d.q_ = static_cast<std::uint32_t>((static_cast<std::uint64_t>(q_) * o.q_ + (std::uint64_t{1} << 31)) >> 32);
      return d;
    } else {
      Decay d;
      d.q_ = q_ * o.q_;
      return d;
    }
  }

  using Rep = std::conditional_t<kIsFixed<S>, std::uint32_t, double>;
  Rep q_{};              ///< Q0.32 (fixed build) or r itself (floating builds)
  bool is_one_ = false;  ///< r = 1 exactly (fixed build; Q0.32 cannot hold 1)
};

}  // namespace toonforce
