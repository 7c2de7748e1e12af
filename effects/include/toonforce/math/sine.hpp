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
      values[static_cast<std::size_t>(i)] =
          scalar_cast<S>(taylor_sin_turns(0.25 * i / kSineTableSegments));
    }
    return values;
  }();
};

/// The polynomial for a Q type, evaluated with 30 fraction bits in 64-bit integers and rounded
/// once at the end: Horner steps in the Q format itself would round at every step (about 4 LSB
/// in Q16.16 instead of 0.5).
template <Scalar S>
constexpr S fixed_polynomial(S q) noexcept {
  using W = typename S::Wide;
  constexpr int kBits = 30;
  constexpr auto coefficient = [](double c) { return static_cast<W>(c * static_cast<double>(W{1} << kBits)); };
  constexpr W c1 = coefficient(kSinPoly1), c3 = coefficient(kSinPoly3);
  constexpr W c5 = coefficient(kSinPoly5), c7 = coefficient(kSinPoly7);
  // q <= 1/4, so q30 < 2^28 and q2 < 2^26; |acc| < 2^37: every product fits in 63 bits.
  const W q30 = W{q.raw()} << (kBits - S::kFracBits);
  const W q2 = (q30 * q30) >> kBits;
  W acc = c5 + ((c7 * q2) >> kBits);
  acc = c3 + ((acc * q2) >> kBits);
  acc = c1 + ((acc * q2) >> kBits);
  return S::from_wide(S::round_shift(acc * q30, 2 * kBits - S::kFracBits));  // Q60 -> Q16
}

/// Splits a phase into its quarter-wave argument q in [0, 1/4] and the sign of the result.
template <Scalar S>
constexpr S quarter_wave(S turns, bool& negative) noexcept {
  S frac{};
  if constexpr (kIsFixed<S>) {
    // Two's complement masking gives the fraction mod 1 for negative phases too.
    frac = S::from_raw(turns.raw() & (S::kOneRaw - 1));
  } else {
    frac = turns - std::floor(turns);
  }
  constexpr S half = scalar_cast<S>(0.5);
  constexpr S quarter = scalar_cast<S>(0.25);
  negative = frac >= half;
  if (negative) frac = frac - half;                // sin(2 pi (q + 1/2)) = -sin(2 pi q)
  if (frac > quarter) frac = half - frac;          // sin(2 pi (1/2 - q)) = sin(2 pi q)
  return frac;
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
    constexpr S kSegmentsPerTurn = scalar_cast<S>(4.0 * detail::kSineTableSegments);
    const S position = q * kSegmentsPerTurn;  // in [0, segments]
    int index = 0;
    S fraction{};
    if constexpr (kIsFixed<S>) {
      index = static_cast<int>(position.raw() >> S::kFracBits);
      fraction = S::from_raw(position.raw() & (S::kOneRaw - 1));
    } else {
      index = static_cast<int>(position);
      fraction = position - static_cast<S>(index);
    }
    if (index >= detail::kSineTableSegments) {  // q == 1/4 exactly
      index = detail::kSineTableSegments - 1;
      fraction = scalar_cast<S>(1.0);
    }
    const auto& table = detail::SineTable<S>::kValues;
    const S lo = table[static_cast<std::size_t>(index)];
    const S hi = table[static_cast<std::size_t>(index) + 1];
    value = lo + (hi - lo) * fraction;
  } else if constexpr (kIsFixed<S>) {
    value = detail::fixed_polynomial(q);
  } else {
    constexpr S c1 = scalar_cast<S>(detail::kSinPoly1);
    constexpr S c3 = scalar_cast<S>(detail::kSinPoly3);
    constexpr S c5 = scalar_cast<S>(detail::kSinPoly5);
    constexpr S c7 = scalar_cast<S>(detail::kSinPoly7);
    const S q2 = q * q;
    value = q * (c1 + q2 * (c3 + q2 * (c5 + q2 * c7)));
  }
  return negative ? -value : value;
}

}  // namespace toonforce
