// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The scalar types every law is built for (spec effects.md §8), as extern templates: the
/// definitions live in effects/src/instantiations.cpp, so each law provably compiles for
/// double, float and Q16.16 in every build, and users do not re-instantiate them.

#include "toonforce/effects/scene.hpp"

/// Applies MACRO(S) to each supported scalar type.
#define TOONFORCE_FOR_EACH_SCALAR(MACRO) \
  MACRO(double)                          \
  MACRO(float)                           \
  MACRO(::toonforce::Q16_16)

// PREFIX is `extern` or nothing and S a template argument: parentheses would not compile.
// NOLINTBEGIN(bugprone-macro-parentheses)
#define TOONFORCE_EFFECT_TEMPLATES(PREFIX, S)                \
  PREFIX template struct ::toonforce::PenaltyWall<S>;        \
  PREFIX template struct ::toonforce::PenaltyWall<S, false>; \
  PREFIX template struct ::toonforce::RealisticFriction<S>;  \
  PREFIX template struct ::toonforce::SuperSlippery<S>;      \
  PREFIX template struct ::toonforce::AnyTangential<S>;      \
  PREFIX template struct ::toonforce::ImpactTransient<S>;    \
  PREFIX template struct ::toonforce::MaybeImpact<S>;        \
  PREFIX template struct ::toonforce::CartoonCliff<S>;       \
  PREFIX template class ::toonforce::RuntimeSceneOf<S, TOONFORCE_BUILTIN_EFFECTS>;
// NOLINTEND(bugprone-macro-parentheses)

#define TOONFORCE_EXTERN_EFFECTS(S) TOONFORCE_EFFECT_TEMPLATES(extern, S)
TOONFORCE_FOR_EACH_SCALAR(TOONFORCE_EXTERN_EFFECTS)
#undef TOONFORCE_EXTERN_EFFECTS
