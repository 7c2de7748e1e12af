// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The library's built-in effect kinds, listed once. Everything that names the built-in kinds
/// takes them from here: the run-time scene (`RuntimeScene<S>`, scene.hpp), its explicit
/// instantiations (instantiations.hpp), the scene-file reader and the live editor
/// (`SceneDescription`, tools/config), and through them every command and the Python module. A
/// test (tests/one_declaration_test.cpp) checks the lists written by hand: the spec's
/// scene-file example and the control protocol's `add` must name every key.
///
/// Adding a built-in effect is: its header (an Effect with a schema, effect.hpp), included
/// below, and its template's name appended to TOONFORCE_BUILTIN_EFFECTS. Appended, not inserted:
/// a kind's place in the list is its index in a scene file's entries and in the run-time
/// scene's dispatch, so the kinds before it keep theirs.

#include <array>
#include <cstddef>
#include <string_view>

#include "toonforce/effects/cliff.hpp"
#include "toonforce/effects/surface.hpp"

/// The built-in kinds, in order: each an effect template over the scalar, fully qualified so
/// the list can be written anywhere, e.g. `RuntimeSceneOf<S, TOONFORCE_BUILTIN_EFFECTS>`.
#define TOONFORCE_BUILTIN_EFFECTS ::toonforce::RuntimeSurface, ::toonforce::CartoonCliff

namespace toonforce {

/// A list of effect kinds and their scene-file keys, in order.
template <template <class> class... Kinds>
struct EffectKinds {
  static constexpr std::size_t kCount = sizeof...(Kinds);
  static constexpr std::array<std::string_view, kCount> kKeys{Kinds<double>::kKey...};
};

/// The built-in kinds (TOONFORCE_BUILTIN_EFFECTS).
using BuiltinEffects = EffectKinds<TOONFORCE_BUILTIN_EFFECTS>;

}  // namespace toonforce
