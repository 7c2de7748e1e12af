// SPDX-License-Identifier: Apache-2.0
#pragma once
/// sin(2 pi p) for a phase `p` in turns, three ways, for every scalar type. The impact
/// transient needs a sine (spec effects.md §4: "computed any way ... so long as the error
/// report states its error"); the precision report compares the methods.
///
/// The phase is taken in turns, not radians, because reducing turns to [0, 1) is exact in
/// every format (for Q16.16 it is a bit mask), while reducing radians needs 2 pi, which a Q
/// format cannot hold exactly. Errors against std::sin in double (measured by
/// tests/math_test.cpp over a dense grid of one turn):
///   - kLibrary:    std::sin of the scalar's own float type; double and float only. In float
///                  the product 2 pi p rounds, so the error grows with the phase (about 1e-6
///                  at two turns).
///   - kPolynomial: odd degree-7 polynomial on a quarter wave, about 6e-7 in double.
///   - kTable:      257-entry quarter-wave table with linear interpolation, about 5e-6.
/// In Q16.16 the polynomial is evaluated in 64-bit integers with 30 fraction bits (within one
/// LSB, 1.5e-5); the table is within three LSB.

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string_view>

#include "toonforce/math/scalar.hpp"

namespace toonforce {

/// kAuto: the default (default_sine_method), what a scene that does not choose gets.
enum class SineMethod : std::uint8_t { kLibrary, kPolynomial, kTable, kAuto };

constexpr std::string_view sine_method_name(SineMethod m) noexcept {
  switch (m) {
    case SineMethod::kLibrary: return "library";
    case SineMethod::kPolynomial: return "polynomial";
    case SineMethod::kTable: return "table";
    case SineMethod::kAuto: return "default";
  }
  return "?";
}

/// The method a name (library, polynomial, table) gives, for the command line.
constexpr std::optional<SineMethod> parse_sine_method(std::string_view name) noexcept {
  for (const SineMethod m : {SineMethod::kLibrary, SineMethod::kPolynomial, SineMethod::kTable}) {
    if (sine_method_name(m) == name) return m;
  }
  return std::nullopt;
}

/// Whether a method exists for scalar S (no library sine without floating point).
template <Scalar S>
constexpr bool sine_method_available(SineMethod m) noexcept {
  return !(kIsFixed<S> && m == SineMethod::kLibrary);
}

/// The method used when a scene does not choose: the polynomial, for every scalar. Its cost is
/// the same for every argument (glibc's sin takes 45 to over 400 instructions, depending on the
/// argument), it is the same code on every scalar and every target (no libm in the tick), and
/// its error, 6e-7 in double, is far below anything a device renders (spec effects.md §4: any
/// method, its error stated).
template <Scalar S>
constexpr SineMethod default_sine_method() noexcept {
  return SineMethod::kPolynomial;
}

namespace detail {

constexpr double kTwoPi = 6.283185307179586476925286766559;

/// Odd fit of sin(2 pi q) on q in [0, 1/4] (weighted least squares, iterated toward
/// minimax; max error 5.9e-7 in exact arithmetic).
constexpr double kSinPoly1 = 6.28316404;
constexpr double kSinPoly3 = -41.33714241;
constexpr double kSinPoly5 = 81.34076899;
constexpr double kSinPoly7 = -70.99342663;

/// sin(2 pi q) by its Taylor series to 1e-17; only used at compile time to fill the table.
constexpr double taylor_sin_turns(double q) noexcept {
  const double x = kTwoPi * q;
  double term = x;
  double sum = x;
  for (int k = 1; k < 20; ++k) {
    term *= -x * x / static_cast<double>((2 * k) * (2 * k + 1));
    sum += term;
  }
  return sum;
}

inline constexpr int kSineTableSegments = 256;

template <Scalar S>
struct SineTable {
  static constexpr std::array<S, kSineTableSegments + 1> kValues = [] {
    std::array<S, kSineTableSegments + 1> values{};
    for (int i = 0; i <= kSineTableSegments; ++i) {
      values[static_cast<std::size_t>(i)] = scalar_cast<S>(taylor_sin_turns(0.25 * i / kSineTableSegments));
    }
    return values;
  }();
};

/// The polynomial for a Q type (Q16.16 takes fixed_polynomial_q16, below), evaluated with 30
/// fraction bits in 64-bit integers and rounded once at the end: Horner steps in the Q format
/// itself would round at every step (about 4 LSB in Q16.16 instead of 0.5).
template <Scalar S>
constexpr S fixed_polynomial(S q) noexcept {
  using W = typename S::Wide;
  constexpr int kBits = 30;
  constexpr auto kCoefficient = [](double c) { return static_cast<W>(c * static_cast<double>(W{1} << kBits)); };
  constexpr W kC1 = kCoefficient(kSinPoly1), kC3 = kCoefficient(kSinPoly3);
  constexpr W kC5 = kCoefficient(kSinPoly5), kC7 = kCoefficient(kSinPoly7);
  // q <= 1/4, so q30 < 2^28 and q2 < 2^26; |acc| < 2^37: every product fits in 63 bits.
  const W q30 = W{q.raw()} << (kBits - S::kFracBits);
  const W q2 = (q30 * q30) >> kBits;
  W acc = kC5 + ((kC7 * q2) >> kBits);
  acc = kC3 + ((acc * q2) >> kBits);
  acc = kC1 + ((acc * q2) >> kBits);
  return S::from_wide(S::round_shift(acc * q30, 2 * kBits - S::kFracBits));  // Q60 -> Q16
}

/// The same polynomial for Q16.16 in 32-bit words: four 32x32 products whose high word is the
/// next step (the 64-bit products above were 59 instructions of the Cortex-M3 tick's
/// bound; these are about 20). Each step keeps what its range allows: q in Q33 (q <= 1/4 fills
/// an unsigned word), q^2 in Q34, the Horner sums in Q23 (c5 + c7 q^2 in [76, 82]), Q25 ([-42,
/// -36]) and Q27 ([3.7, 6.3]), the sine in Q28. c1 is rounded up by 2 units of 2^-27 (1.5e-8):
/// with it, each of the 16,385 quarter-wave arguments gives the 64-bit evaluation's result
/// (math_test compares all of them), so no Q16.16 force changed.
constexpr std::int32_t fixed_polynomial_q16(std::int32_t q_raw) noexcept {
  constexpr auto kCoefficient = [](double c, int bits) {
    const double scaled = c * static_cast<double>(std::int64_t{1} << bits);
    return static_cast<std::int32_t>(scaled < 0.0 ? scaled - 0.5 : scaled + 0.5);
  };
  constexpr std::int32_t kC7 = kCoefficient(kSinPoly7, 21), kC5 = kCoefficient(kSinPoly5, 23);
  constexpr std::int32_t kC3 = kCoefficient(kSinPoly3, 25), kC1 = kCoefficient(kSinPoly1, 27) + 2;
  constexpr auto kHigh = [](std::int32_t a, std::int32_t b) {  // floor(a b / 2^32): SMULL's high word
    return static_cast<std::int32_t>((std::int64_t{a} * b) >> 32);
  };
  const std::uint32_t q33 = static_cast<std::uint32_t>(q_raw) << 17;            // <= 2^31
  const auto q2 = static_cast<std::int32_t>((std::uint64_t{q33} * q33) >> 32);  // <= 2^30
  std::int32_t acc = kC5 + kHigh(kC7, q2);
  acc = kC3 + kHigh(acc, q2);
  acc = kC1 + kHigh(acc, q2);
  const auto sine = static_cast<std::uint32_t>((std::uint64_t{static_cast<std::uint32_t>(acc)} * q33) >> 32);
  return static_cast<std::int32_t>((sine + (1U << 11)) >> 12);  // >= 0: half up is half away from zero
}

/// Splits a phase into its quarter-wave argument q in [0, 1/4] and the sign of the result.
template <Scalar S>
constexpr S quarter_wave(S turns, bool& negative) noexcept {
  // sin(2 pi (q + 1/2)) = -sin(2 pi q); sin(2 pi (1/2 - q)) = sin(2 pi q).
  if constexpr (kIsFixed<S>) {
    // Two's complement masking gives the fraction mod 1 for negative phases too; in [0, 1),
    // it is folded without a saturation test.
    auto raw = turns.raw() & (S::kOneRaw - 1);
    negative = raw >= S::kOneRaw / 2;
    if (negative) raw -= S::kOneRaw / 2;
    if (raw > S::kOneRaw / 4) raw = S::kOneRaw / 2 - raw;
    return S::from_raw(raw);
  } else {
    S frac = turns - std::floor(turns);
    constexpr S kHalf = scalar_cast<S>(0.5);
    constexpr S kQuarter = scalar_cast<S>(0.25);
    negative = frac >= kHalf;
    if (negative) frac = frac - kHalf;
    if (frac > kQuarter) frac = kHalf - frac;
    return frac;
  }
}

}  // namespace detail

/// sin(2 pi turns) with the chosen method. kLibrary on a Q type falls back to kPolynomial
/// (scene loading rejects that combination, so it only matters to direct callers).
template <Scalar S>
constexpr S sin_turns(S turns, SineMethod method) noexcept {
  if (method == SineMethod::kAuto) method = default_sine_method<S>();
  if (method == SineMethod::kLibrary) {
    if constexpr (!kIsFixed<S>) {
      return std::sin(static_cast<S>(detail::kTwoPi) * turns);
    }
  }
  bool negative = false;
  const S q = detail::quarter_wave(turns, negative);
  S value{};
  if (method == SineMethod::kTable) {
    const auto& table = detail::SineTable<S>::kValues;
    if constexpr (kIsFixed<S>) {
      // Steps none of which can leave the range, so without a saturation test (the
      // method is chosen at run time, so the tick's bound counts the dearer one): q * 1024 is
      // exact, a shift (q <= 1/4: below 2^(F + 8)); hi - lo is a few LSB; lo plus a share of it
      // lies between lo and hi. The values are operator*'s and operator+'s.
      static_assert(4 * detail::kSineTableSegments == 1 << 10 && S::kFracBits <= 22);
      const auto position = static_cast<std::uint32_t>(q.raw()) << 10;  // segments, F fraction bits
      auto index = static_cast<std::size_t>(position >> S::kFracBits);
      auto fraction = static_cast<typename S::Raw>(position & static_cast<std::uint32_t>(S::kOneRaw - 1));
      if (index >= detail::kSineTableSegments) {  // q == 1/4 exactly
        index = detail::kSineTableSegments - 1;
        fraction = S::kOneRaw;
      }
      const typename S::Raw lo = table[index].raw();
      const auto step = static_cast<typename S::Wide>(table[index + 1].raw() - lo);
      value = S::from_raw(lo + S::from_product_in_range(step * fraction).raw());
    } else {
      const S position = q * static_cast<S>(4 * detail::kSineTableSegments);  // in [0, segments]
      auto index = static_cast<std::size_t>(position);
      S fraction = position - static_cast<S>(index);
      if (index >= detail::kSineTableSegments) {  // q == 1/4 exactly
        index = detail::kSineTableSegments - 1;
        fraction = S{1};
      }
      value = table[index] + (table[index + 1] - table[index]) * fraction;
    }
  } else if constexpr (kIsFixed<S>) {
    if constexpr (S::kFracBits == 16 && sizeof(typename S::Raw) == 4) {
      value = S::from_raw(detail::fixed_polynomial_q16(q.raw()));  // in [0, 1]: no saturation
    } else {
      value = detail::fixed_polynomial(q);
    }
  } else {
    constexpr S kC1 = scalar_cast<S>(detail::kSinPoly1);
    constexpr S kC3 = scalar_cast<S>(detail::kSinPoly3);
    constexpr S kC5 = scalar_cast<S>(detail::kSinPoly5);
    constexpr S kC7 = scalar_cast<S>(detail::kSinPoly7);
    const S q2 = q * q;
    value = q * (kC1 + q2 * (kC3 + q2 * (kC5 + q2 * kC7)));
  }
  if constexpr (kIsFixed<S>) {
    return negative ? S::from_raw(-value.raw()) : value;  // |value| <= 1: no saturation test
  } else {
    return negative ? -value : value;
  }
}

}  // namespace toonforce
