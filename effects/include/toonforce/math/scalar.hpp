// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The scalar types the force laws are instantiated for, and the few math functions the laws
/// use, spelled the same for all of them: `double` (the reference), `float`, and `Q16_16`.
/// Laws call `sqrt`, `abs`, `is_finite`, `min`, `max` unqualified inside namespace toonforce;
/// conversions from and to double are explicit (`scalar_cast`, `to_double`).

#include <cmath>
#include <concepts>
#include <string_view>

#include "toonforce/math/fixed.hpp"

namespace toonforce {

/// A scalar type the laws can be instantiated for.
template <class S>
concept Scalar = std::same_as<S, double> || std::same_as<S, float> || kIsFixed<S>;

/// Explicit conversion from double (round to nearest; saturates with the flag for Q types).
template <Scalar S>
constexpr S scalar_cast(double value) noexcept {
  if constexpr (kIsFixed<S>) {
    return S::from_double(value);
  } else {
    return static_cast<S>(value);
  }
}

template <Scalar S>
constexpr double to_double(S value) noexcept {
  if constexpr (kIsFixed<S>) {
    return value.to_double();
  } else {
    return static_cast<double>(value);
  }
}

/// True if `value` is a finite number that converts to S without overflow or saturation.
template <Scalar S>
constexpr bool representable(double value) noexcept {
  if constexpr (kIsFixed<S>) {
    return S::representable(value);
  } else if constexpr (std::same_as<S, float>) {
    return std::isfinite(value) && std::abs(value) <= static_cast<double>(3.4e38F);
  } else {
    return std::isfinite(value);
  }
}

/// Name used on the command line and in reports.
template <Scalar S>
constexpr std::string_view scalar_name() noexcept {
  if constexpr (std::same_as<S, double>) {
    return "double";
  } else if constexpr (std::same_as<S, float>) {
    return "float";
  } else {
    return "q16.16";
  }
}

inline double sqrt(double x) noexcept { return std::sqrt(x); }
inline float sqrt(float x) noexcept { return std::sqrt(x); }
inline double abs(double x) noexcept { return std::fabs(x); }
inline float abs(float x) noexcept { return std::fabs(x); }
inline bool is_finite(double x) noexcept { return std::isfinite(x); }
inline bool is_finite(float x) noexcept { return std::isfinite(x); }

/// 1 / x for x > 0: in a Q format `Fixed::reciprocal_of_positive`, one 32-bit division (a
/// quotient that divides several values is cheaper as this and products).
template <Scalar S>
constexpr S reciprocal_of_positive(S x) noexcept {
  if constexpr (kIsFixed<S>) {
    return S::reciprocal_of_positive(x);
  } else {
    return S{1} / x;
  }
}

template <Scalar S>
constexpr S min(S a, S b) noexcept {
  return b < a ? b : a;
}
template <Scalar S>
constexpr S max(S a, S b) noexcept {
  return a < b ? b : a;
}

}  // namespace toonforce
