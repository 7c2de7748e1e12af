// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What an effect is, and how the rest of the stack asks it for what it carries. An effect is a
/// type with
///   using Scalar;  struct Params;  struct State;  static constexpr Needs kNeeds;
///   static constexpr std::string_view kKey;           // its scene-file table: [[kKey]]
///   static Vec3<S> force(const Params&, State&, const TickInput<S>&) noexcept;
/// and, when it has them:
///   static constexpr std::size_t kActiveSlots;        // parts that inject energy by design
///   static constexpr std::size_t active_slots(const Params&);  // of those, what this one has
///   static Vec3<S> force(const Params&, State&, const TickInput<S>&, ActiveForce<S>* active) noexcept;
///                                                     // (reports each of its slots every tick)
///   static constexpr std::array<ValueInfo, N> kValues;  // what it shows in traces and the viewer
///   static bool describe(const Params&, const State&, const TickInput<S>&, double* values) noexcept;
///                                                     // fills kValues; true while in contact
///   static constexpr auto schema();                   // its scene-file keys (schema.hpp)
///   static void check(const Params&, schema::Problems&, ScalarKind);  // checks across keys
///   static constexpr Needs needs(const Params&) noexcept;  // what this instance needs
///   static constexpr std::size_t kMaxPerScene;        // capacity in a run-time scene (default 8)
///   static constexpr std::array<std::string_view, N> kEvents;  // one-shot events a live scene
///   static constexpr bool fire(const Params&, State&, std::size_t event, double value,
///                              Instant now) noexcept;  // may fire (false: refused)
/// force() runs on every servo tick: no allocation, exception, lock, system call or clock.
/// Those five optional parts are what the scene-file reader, the run-time scene, the passivity
/// controller, telemetry and the viewer take from an effect; nothing else in the library names
/// an effect, so a program adds its own (examples/) without editing the library.

#include <array>
#include <concepts>
#include <cstddef>
#include <string_view>
#include <type_traits>

#include "toonforce/effects/tick.hpp"

namespace toonforce {

// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class E>
concept Effect =
    requires {
      typename E::Scalar;
      typename E::Params;
      typename E::State;
      { E::kNeeds } -> std::convertible_to<Needs>;
      { E::kKey } -> std::convertible_to<std::string_view>;
    } &&
    (requires(const typename E::Params& p, typename E::State& s, const TickInput<typename E::Scalar>& in) {
      { E::force(p, s, in) } noexcept -> std::same_as<Vec3<typename E::Scalar>>;
    } ||
     requires(const typename E::Params& p, typename E::State& s, const TickInput<typename E::Scalar>& in,
              ActiveForce<typename E::Scalar>* active) {
       { E::force(p, s, in, active) } noexcept -> std::same_as<Vec3<typename E::Scalar>>;
     });
// clang-format on

/// An effect a scene file can describe: it has a schema.
// clang-format off
template <class E>
concept FileEffect = Effect<E> && requires { E::schema(); };
// clang-format on

namespace effect {

/// Energy-injecting parts of E (0 unless declared).
template <Effect E>
inline constexpr std::size_t kActiveSlots = [] {
  if constexpr (requires { E::kActiveSlots; }) {
    return std::size_t{E::kActiveSlots};
  } else {
    return std::size_t{0};
  }
}();

/// The values E shows (none unless declared).
template <Effect E>
inline constexpr auto kValues = [] {
  if constexpr (requires { E::kValues; }) {
    return E::kValues;
  } else {
    return std::array<ValueInfo, 0>{};
  }
}();

template <Effect E>
inline constexpr std::size_t kValueCount = kValues<E>.size();

template <Effect E>
inline constexpr std::size_t kMaxPerScene = [] {
  if constexpr (requires { E::kMaxPerScene; }) {
    return std::size_t{E::kMaxPerScene};
  } else {
    return std::size_t{8};
  }
}();

/// E's force on this tick; `active` holds kActiveSlots<E> entries (E writes them all).
template <Effect E>
constexpr Vec3<typename E::Scalar> force(const typename E::Params& p, typename E::State& s,
                                         const TickInput<typename E::Scalar>& in,
                                         ActiveForce<typename E::Scalar>* active) noexcept {
  if constexpr (requires { E::force(p, s, in, active); }) {
    return E::force(p, s, in, active);
  } else {
    static_cast<void>(active);
    return E::force(p, s, in);
  }
}

/// Fills kValueCount<E> values; true while the HIP touches E's geometry.
template <Effect E>
constexpr bool describe(const typename E::Params& p, const typename E::State& s,
                        const TickInput<typename E::Scalar>& in, double* values) noexcept {
  if constexpr (requires { E::describe(p, s, in, values); }) {
    return E::describe(p, s, in, values);
  } else {
    static_cast<void>(p);
    static_cast<void>(s);
    static_cast<void>(in);
    static_cast<void>(values);
    return false;
  }
}

/// How many of its kActiveSlots this instance uses (all unless E says fewer): a run-time scene
/// gives it only those, so a surface that cannot inject costs the passivity stage nothing.
template <Effect E>
constexpr std::size_t active_slots(const typename E::Params& p) noexcept {
  if constexpr (requires { E::active_slots(p); }) {
    return E::active_slots(p);
  } else {
    static_cast<void>(p);
    return kActiveSlots<E>;
  }
}

/// Whether this instance's state can change (true unless E says it cannot: a surface without
/// an impact keeps its state as it was). A run-time scene copies only the states that can.
template <Effect E>
constexpr bool stateful(const typename E::Params& p) noexcept {
  if constexpr (std::is_empty_v<typename E::State>) {
    static_cast<void>(p);
    return false;
  } else if constexpr (requires { E::stateful(p); }) {
    return E::stateful(p);
  } else {
    static_cast<void>(p);
    return true;
  }
}

/// What this instance needs (the type's kNeeds unless E says better).
template <Effect E>
constexpr Needs needs(const typename E::Params& p) noexcept {
  if constexpr (requires { E::needs(p); }) {
    return E::needs(p);
  } else {
    static_cast<void>(p);
    return E::kNeeds;
  }
}

/// The one-shot events E accepts from a live scene (none unless declared): "impact" on a
/// surface shakes it on demand, "look_down" on a cliff drops the character that is over the gap.
template <Effect E>
inline constexpr auto kEvents = [] {
  if constexpr (requires { E::kEvents; }) {
    return E::kEvents;
  } else {
    return std::array<std::string_view, 0>{};
  }
}();

/// Fires E's event number `event` (an index into kEvents<E>) with `value` on this instance at
/// tick `now`, between two ticks; false if E has no such event or this instance cannot take it.
template <Effect E>
constexpr bool fire(const typename E::Params& p, typename E::State& s, std::size_t event, double value,
                    Instant now) noexcept {
  if constexpr (requires { E::fire(p, s, event, value, now); }) {
    return E::fire(p, s, event, value, now);
  } else {
    static_cast<void>(p);
    static_cast<void>(s);
    static_cast<void>(event);
    static_cast<void>(value);
    static_cast<void>(now);
    return false;
  }
}

/// E's checks across keys, if it has any.
template <Effect E>
void check(const typename E::Params& p, schema::Problems& problems, ScalarKind scalar) {
  if constexpr (requires { E::check(p, problems, scalar); }) E::check(p, problems, scalar);
}

}  // namespace effect
}  // namespace toonforce
