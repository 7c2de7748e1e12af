// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The scalar type as a run-time choice (`--scalar double|float|q16.16`, a scene checked for
/// Q16.16), and the one place where that choice becomes a template argument:
///
///   return with_scalar(kind, [&]<Scalar S>() { return run_as<S>(...); });
///
/// A build may leave scalars out (the firmware-style build keeps only Q16.16: define
/// TOONFORCE_ONLY_Q16_16); `with_scalar` then calls `unavailable(kind)` for the others instead of
/// instantiating them.

#include <optional>
#include <string_view>
#include <utility>

#include "toonforce/math/scalar.hpp"

namespace toonforce {

enum class ScalarKind { kDouble, kFloat, kQ16_16 };

inline constexpr ScalarKind kAllScalarKinds[] = {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16};

constexpr std::string_view scalar_kind_name(ScalarKind kind) noexcept {
  switch (kind) {
    case ScalarKind::kDouble: return "double";
    case ScalarKind::kFloat: return "float";
    case ScalarKind::kQ16_16: return "q16.16";
  }
  return "?";
}

constexpr std::optional<ScalarKind> parse_scalar_kind(std::string_view name) noexcept {
  for (const ScalarKind k : kAllScalarKinds) {
    if (scalar_kind_name(k) == name) return k;
  }
  return std::nullopt;
}

template <Scalar S>
constexpr ScalarKind scalar_kind_of() noexcept {
  if constexpr (kIsFixed<S>) {
    return ScalarKind::kQ16_16;
  } else if constexpr (std::same_as<S, float>) {
    return ScalarKind::kFloat;
  } else {
    return ScalarKind::kDouble;
  }
}

/// Whether this build instantiates code for `kind`.
constexpr bool scalar_built(ScalarKind kind) noexcept {
#if defined(TOONFORCE_ONLY_Q16_16) && TOONFORCE_ONLY_Q16_16
  return kind == ScalarKind::kQ16_16;
#else
  static_cast<void>(kind);
  return true;
#endif
}

/// Calls `f.template operator()<S>()` for the scalar `kind` names, or `unavailable(kind)` when
/// this build leaves that scalar out. Both must return the same type.
template <class F, class Unavailable>
decltype(auto) with_scalar(ScalarKind kind, F&& f, Unavailable&& unavailable) {
#if defined(TOONFORCE_ONLY_Q16_16) && TOONFORCE_ONLY_Q16_16
  if (kind == ScalarKind::kQ16_16) return std::forward<F>(f).template operator()<Q16_16>();
  return std::forward<Unavailable>(unavailable)(kind);
#else
  static_cast<void>(unavailable);
  switch (kind) {
    case ScalarKind::kFloat: return std::forward<F>(f).template operator()<float>();
    case ScalarKind::kQ16_16: return std::forward<F>(f).template operator()<Q16_16>();
    case ScalarKind::kDouble: break;
  }
  return std::forward<F>(f).template operator()<double>();
#endif
}

}  // namespace toonforce
