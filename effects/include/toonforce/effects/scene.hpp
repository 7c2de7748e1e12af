// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Scenes: the sum of their effects' forces, in order (spec effects.md §0).
///
/// `Scene<Effects...>` is composed at compile time and contains only its effects: its state is
/// theirs, its `kNeeds` the union of theirs, so a stage no effect needs is compiled out.
/// `RuntimeSceneOf<S, Kinds...>` holds what a scene file describes, any number of effects of the
/// given kinds in file order, in fixed capacity sized at compile time; `RuntimeScene<S>` is the
/// library's (surfaces and cliffs). A program adds a kind of its own by naming it there.
///
/// Both give the servo loop the same things (SceneType): the force, updating the state in place
/// (the caller keeps the previous state when it must discard a tick, spec §6.1) and reporting
/// the active parts into `active` (kActiveCapacity entries, `active_slots()` of them in use);
/// the values the effects show (`describe`, `value_count()` of them); and which effect each
/// slot and value belongs to (`effect_info`), for telemetry and the viewer.

#include <array>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <span>
#include <tuple>
#include <utility>

#include "toonforce/effects/builtin.hpp"
#include "toonforce/effects/cliff.hpp"
#include "toonforce/effects/effect.hpp"
#include "toonforce/effects/params_check.hpp"
#include "toonforce/effects/surface.hpp"

namespace toonforce {

/// One effect of a scene, for naming its values: `key` and `number` (from 1 among effects of
/// that key, in order) give "surface2.impact_t".
struct EffectInfo {
  std::string_view key;
  std::size_t number = 0;
  std::span<const ValueInfo> values;
  std::size_t value_offset = 0;   ///< where its values start in describe()'s output
  std::size_t active_offset = 0;  ///< where its active slots start
  std::size_t active_slots = 0;
};

/// What the servo loop needs of a scene, compile-time or run-time.
// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class T>
concept SceneType = requires(const T& scene, typename T::State& s, const typename T::State& cs,
                             const TickInput<typename T::Scalar>& in, ActiveForce<typename T::Scalar>* active,
                             double* values, std::size_t i) {
  { T::kNeeds } -> std::convertible_to<Needs>;
  { T::kActiveCapacity } -> std::convertible_to<std::size_t>;
  { T::kValueCapacity } -> std::convertible_to<std::size_t>;
  { scene.force(in, s, active) } noexcept -> std::same_as<Vec3<typename T::Scalar>>;
  { scene.force(in, cs, s, active) } noexcept -> std::same_as<Vec3<typename T::Scalar>>;
  { scene.needs() } noexcept -> std::same_as<Needs>;
  { scene.active_slots() } noexcept -> std::same_as<std::size_t>;
  { scene.value_count() } noexcept -> std::same_as<std::size_t>;
  { scene.describe(cs, in, values) } noexcept -> std::same_as<bool>;
  { scene.effect_count() } noexcept -> std::same_as<std::size_t>;
  { scene.effect_info(i) } noexcept -> std::same_as<EffectInfo>;
};
// clang-format on

template <Effect First, Effect... Rest>
class Scene {
  using Effects = std::tuple<First, Rest...>;
  template <std::size_t I>
  using E = std::tuple_element_t<I, Effects>;
  static constexpr std::size_t kCount = 1 + sizeof...(Rest);
  static constexpr std::array<std::size_t, kCount> kSlots{effect::kActiveSlots<First>, effect::kActiveSlots<Rest>...};
  static constexpr std::array<std::size_t, kCount> kValueCounts{effect::kValueCount<First>,
                                                                effect::kValueCount<Rest>...};
  static constexpr std::array<std::string_view, kCount> kKeys{First::kKey, Rest::kKey...};
  template <std::size_t N>
  static constexpr std::size_t offset(const std::array<std::size_t, kCount>& sizes) {
    std::size_t sum = 0;
    for (std::size_t i = 0; i < N; ++i) sum += sizes[i];
    return sum;
  }

 public:
  using Scalar = typename First::Scalar;
  static_assert((std::same_as<Scalar, typename Rest::Scalar> && ...), "one scalar per scene");
  using S = Scalar;
  using Params = std::tuple<typename First::Params, typename Rest::Params...>;
  struct State {
    std::tuple<typename First::State, typename Rest::State...> effects{};
  };
  static constexpr Needs kNeeds = (First::kNeeds | ... | Rest::kNeeds);
  static constexpr std::size_t kActiveCapacity = offset<kCount>(kSlots);
  static constexpr std::size_t kValueCapacity = offset<kCount>(kValueCounts);

  constexpr explicit Scene(typename First::Params first, typename Rest::Params... rest) noexcept
      : params_{first, rest...} {}

  constexpr Vec3<S> force(const TickInput<S>& in, State& state, ActiveForce<S>* active) const noexcept {
    return sum(in, state, active, std::make_index_sequence<kCount>{});
  }
  /// The force from the state `from`, leaving the effects' new states in `to` (`from` kept).
  constexpr Vec3<S> force(const TickInput<S>& in, const State& from, State& to, ActiveForce<S>* active) const noexcept {
    to = from;
    return force(in, to, active);
  }
  constexpr Needs needs() const noexcept { return kNeeds; }
  constexpr std::size_t active_slots() const noexcept { return kActiveCapacity; }
  constexpr std::size_t value_count() const noexcept { return kValueCapacity; }
  constexpr bool describe(const State& state, const TickInput<S>& in, double* values) const noexcept {
    return describe_all(state, in, values, std::make_index_sequence<kCount>{});
  }
  constexpr std::size_t effect_count() const noexcept { return kCount; }
  constexpr EffectInfo effect_info(std::size_t i) const noexcept {
    EffectInfo info;
    if (i >= kCount) return info;
    info.key = kKeys[i];
    for (std::size_t j = 0; j <= i; ++j) info.number += kKeys[j] == kKeys[i] ? std::size_t{1} : std::size_t{0};
    info.values = values_of(i, std::make_index_sequence<kCount>{});
    for (std::size_t j = 0; j < i; ++j) {
      info.value_offset += kValueCounts[j];
      info.active_offset += kSlots[j];
    }
    info.active_slots = kSlots[i];
    return info;
  }
  constexpr const Params& params() const noexcept { return params_; }

 private:
  template <std::size_t I0, std::size_t... I>
  constexpr Vec3<S> sum(const TickInput<S>& in, State& state, ActiveForce<S>* active,
                        std::index_sequence<I0, I...>) const noexcept {
    // The first effect's force is the start: 0 + f is f in a Q format, so a one-effect scene
    // adds nothing (three saturating adds of every tick's bound). Floating point
    // starts from +0 as it did: 0 + (-0) is +0, and the traces print the sign.
    Vec3<S> total{};
    if constexpr (kIsFixed<S>) {
      total = force_of<I0>(in, state, active);
    } else {
      total += force_of<I0>(in, state, active);
    }
    // The comma fold runs left to right: effects add in declaration order.
    ((total += force_of<I>(in, state, active)), ...);
    return total;
  }
  template <std::size_t I>
  constexpr Vec3<S> force_of(const TickInput<S>& in, State& state, ActiveForce<S>* active) const noexcept {
    return effect::force<E<I>>(std::get<I>(params_), std::get<I>(state.effects), in, active + offset<I>(kSlots));
  }
  template <std::size_t... I>
  constexpr bool describe_all(const State& state, const TickInput<S>& in, double* values,
                              std::index_sequence<I...>) const noexcept {
    bool contact = false;
    ((contact = effect::describe<E<I>>(std::get<I>(params_), std::get<I>(state.effects), in,
                                       values + offset<I>(kValueCounts)) ||
                contact),
     ...);
    return contact;
  }
  template <std::size_t... I>
  static constexpr std::span<const ValueInfo> values_of(std::size_t i, std::index_sequence<I...>) noexcept {
    std::span<const ValueInfo> out;
    ((i == I ? void(out = std::span<const ValueInfo>(effect::kValues<E<I>>)) : void()), ...);
    return out;
  }

  Params params_;
};

/// Defined only by tests and fuzz targets, to write the bytes another process could write into
/// a live scene's update (control/scene_updates.hpp).
struct ForgeAccess;

/// The scene a file describes: effects of the kinds `Kinds<S>` (each an Effect template over the
/// scalar), any number of each up to its kMaxPerScene, forces added in the order they were added.
template <Scalar S, template <class> class... Kinds>
class RuntimeSceneOf {
  using Effects = std::tuple<Kinds<S>...>;
  static constexpr std::size_t kKinds = sizeof...(Kinds);
  static_assert(kKinds > 0 && kKinds < 256);

 public:
  template <std::size_t I>
  using Kind = std::tuple_element_t<I, Effects>;
  using Scalar = S;
  /// Upper bound of what a loaded scene may need; `needs()` says what this one needs.
  static constexpr Needs kNeeds = (Kinds<S>::kNeeds | ...);
  static constexpr std::size_t kMaxEffects = (effect::kMaxPerScene<Kinds<S>> + ...);
  static constexpr std::size_t kActiveCapacity =
      ((effect::kMaxPerScene<Kinds<S>> * effect::kActiveSlots<Kinds<S>>)+...);
  static constexpr std::size_t kValueCapacity = ((effect::kMaxPerScene<Kinds<S>> * effect::kValueCount<Kinds<S>>)+...);

  struct State {
    std::tuple<std::array<typename Kinds<S>::State, effect::kMaxPerScene<Kinds<S>>>...> effects{};
  };

  /// Index of the kind whose key is `key`, or kKinds.
  static constexpr std::size_t kind_index(std::string_view key) noexcept {
    constexpr std::array<std::string_view, kKinds> kKeys{Kinds<S>::kKey...};
    for (std::size_t i = 0; i < kKinds; ++i) {
      if (kKeys[i] == key) return i;
    }
    return kKinds;
  }
  static constexpr std::size_t kind_count() noexcept { return kKinds; }

  /// Appends an effect of kind I after those already added; false when that kind is full.
  template <std::size_t I>
  constexpr bool add(const typename Kind<I>::Params& p) noexcept {
    using E = Kind<I>;
    std::size_t& n = counts_[I];
    if (n == effect::kMaxPerScene<E>) return false;
    std::get<I>(params_)[n] = p;
    order_[effect_count_++] =
        Entry{static_cast<std::uint8_t>(I), static_cast<std::uint8_t>(n), static_cast<std::uint16_t>(active_slots_),
              static_cast<std::uint16_t>(value_count_), effect::stateful<E>(p)};
    ++n;
    active_slots_ += effect::active_slots<E>(p);
    value_count_ += effect::kValueCount<E>;
    needs_ = needs_ | effect::needs<E>(p);
    return true;
  }
  /// The same, by effect type.
  template <class E>
  constexpr bool add(const typename E::Params& p) noexcept {
    return add<index_of<E>(std::make_index_sequence<kKinds>{})>(p);
  }

  constexpr Vec3<S> force(const TickInput<S>& in, State& state, ActiveForce<S>* active) const noexcept {
    Vec3<S> total{};
    for (std::size_t i = 0; i < effect_count_; ++i) {
      dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
        total += effect::force<Kind<I>>(std::get<I>(params_)[e.index], std::get<I>(state.effects)[e.index], in,
                                        active + e.active_offset);
      });
    }
    return total;
  }
  /// The force from the state `from`, leaving the effects' new states in `to` (`from` kept):
  /// each effect's state is copied just before it runs, only for the effects in use.
  constexpr Vec3<S> force(const TickInput<S>& in, const State& from, State& to, ActiveForce<S>* active) const noexcept {
    Vec3<S> total{};
    for (std::size_t i = 0; i < effect_count_; ++i) {
      dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
        auto& state = std::get<I>(to.effects)[e.index];
        if (e.stateful) state = std::get<I>(from.effects)[e.index];  // else both copies stay as they were
        total += effect::force<Kind<I>>(std::get<I>(params_)[e.index], state, in, active + e.active_offset);
      });
    }
    return total;
  }
  constexpr Needs needs() const noexcept { return needs_; }
  constexpr std::size_t active_slots() const noexcept { return active_slots_; }
  constexpr std::size_t value_count() const noexcept { return value_count_; }
  constexpr bool describe(const State& state, const TickInput<S>& in, double* values) const noexcept {
    bool contact = false;
    for (std::size_t i = 0; i < effect_count_; ++i) {
      dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
        contact = effect::describe<Kind<I>>(std::get<I>(params_)[e.index], std::get<I>(state.effects)[e.index], in,
                                            values + e.value_offset) ||
                  contact;
      });
    }
    return contact;
  }
  constexpr std::size_t effect_count() const noexcept { return effect_count_; }
  constexpr EffectInfo effect_info(std::size_t i) const noexcept {
    EffectInfo info;
    if (i >= effect_count_) return info;
    dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
      info.key = Kind<I>::kKey;
      info.number = e.index + 1u;
      info.values = std::span<const ValueInfo>(effect::kValues<Kind<I>>);
      info.active_slots = effect::active_slots<Kind<I>>(std::get<I>(params_)[e.index]);
    });
    info.value_offset = order_[i].value_offset;
    info.active_offset = order_[i].active_offset;
    return info;
  }

  /// Live scenes. `now` holds, for each effect of this scene, the state of the effect
  /// of the previous scene's `from` it continues (`continues[i]` for this scene's i-th effect in
  /// order: the index among effects of its kind in the previous scene, or -1 for a new effect,
  /// whose state starts fresh). Between two ticks, never inside one.
  constexpr void carry(const State& from, State& now, const std::int16_t* continues) const noexcept {
    for (std::size_t i = 0; i < effect_count_; ++i) {
      dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
        auto& state = std::get<I>(now.effects)[e.index];
        const std::int16_t old = continues[i];
        const auto& before = std::get<I>(from.effects);
        state = old >= 0 && static_cast<std::size_t>(old) < before.size() ? before[static_cast<std::size_t>(old)]
                                                                          : typename Kind<I>::State{};
      });
    }
  }
  /// The number of event `name` of the i-th effect (effect::kEvents), or -1 if it has none such.
  constexpr int event_index(std::size_t i, std::string_view name) const noexcept {
    int found = -1;
    if (i >= effect_count_) return found;
    dispatch(order_[i], [&]<std::size_t I>(const Entry&) {
      const auto& events = effect::kEvents<Kind<I>>;
      for (std::size_t j = 0; j < events.size(); ++j) {
        if (events[j] == name) found = static_cast<int>(j);
      }
    });
    return found;
  }
  /// Fires event `event` of the i-th effect with `value` at `now` (effect::fire), between two
  /// ticks; false if it refused.
  constexpr bool fire(State& state, std::size_t i, std::size_t event, double value, Instant now) const noexcept {
    bool fired = false;
    if (i >= effect_count_) return fired;
    dispatch(order_[i], [&]<std::size_t I>(const Entry& e) {
      fired =
          effect::fire<Kind<I>>(std::get<I>(params_)[e.index], std::get<I>(state.effects)[e.index], event, value, now);
    });
    return fired;
  }

  /// Live scenes: makes this scene the effects of `untrusted`, a copy of bytes another process
  /// wrote (docs/spec/live-scenes.md), or says it cannot: nothing of `untrusted` but its order's
  /// kinds and indices and its effects' parameters is used, and those are checked first. For
  /// each of its effect_count() effects in order (at most kMaxEffects), the kind must be one of
  /// this scene's, the index the next of that kind (0, 1, 2, ...: below its kMaxPerScene), the
  /// parameters pass effect::params_ok (params_check.hpp); each is then added again, which
  /// computes the offsets, counts, needs and which states are kept anew. The counts and offsets
  /// `untrusted` claims must be those. False: refused (this scene is then partly built: do not
  /// use it). Bounded work, no allocation.
  bool assign_checked(const RuntimeSceneOf& untrusted) noexcept {
    counts_ = {};
    effect_count_ = active_slots_ = value_count_ = 0;
    needs_ = Needs::kNone;
    if (untrusted.effect_count_ > kMaxEffects) return false;
    // Bounded by the capacity as well: the order is never read past its end.
    const std::size_t n = untrusted.effect_count_ < kMaxEffects ? untrusted.effect_count_ : kMaxEffects;
    for (std::size_t i = 0; i < n; ++i) {
      const Entry& e = untrusted.order_[i];  // its integers only: `stateful` is not loaded
      if (e.kind >= kKinds) return false;    // (dispatch would find no kind either)
      bool added = false;
      dispatch(e, [&]<std::size_t I>(const Entry&) {
        const std::size_t index = e.index;
        if (index >= effect::kMaxPerScene<Kind<I>> || index != counts_[I]) return;
        const auto& p = std::get<I>(untrusted.params_)[index];
        if (!effect::params_ok<Kind<I>>(p)) return;
        added = add<I>(p);
      });
      if (!added) return false;
      if (e.active_offset != order_[i].active_offset || e.value_offset != order_[i].value_offset) return false;
    }
    return untrusted.counts_ == counts_ && untrusted.active_slots_ == active_slots_ &&
           untrusted.value_count_ == value_count_;
  }
  /// Live scenes: whether `continues` (one per effect of this scene, in order) names, for each,
  /// -1 (a new effect) or an effect of its kind that `previous` has.
  constexpr bool continues_ok(const RuntimeSceneOf& previous, const std::int16_t* continues) const noexcept {
    for (std::size_t i = 0; i < effect_count_; ++i) {
      const std::int16_t old = continues[i];
      if (old < -1 || (old >= 0 && static_cast<std::size_t>(old) >= previous.counts_[order_[i].kind])) return false;
    }
    return true;
  }
  /// Live scenes: whether the i-th effect has an event number `event`, and `value` is a finite
  /// number S holds.
  bool takes_event(std::size_t i, std::size_t event, double value) const noexcept {
    if (i >= effect_count_ || !representable<S>(value)) return false;
    std::size_t events = 0;
    dispatch(order_[i], [&]<std::size_t I>(const Entry&) { events = effect::kEvents<Kind<I>>.size(); });
    return event < events;
  }

  /// How many effects of kind I, and the n-th of them.
  template <std::size_t I>
  constexpr std::size_t count() const noexcept {
    return counts_[I];
  }
  template <std::size_t I>
  constexpr const typename Kind<I>::Params& params(std::size_t n) const noexcept {
    return std::get<I>(params_)[n];
  }
  template <class E>
  constexpr std::size_t count() const noexcept {
    return counts_[index_of<E>(std::make_index_sequence<kKinds>{})];
  }
  template <class E>
  constexpr const typename E::Params& params(std::size_t n) const noexcept {
    return std::get<index_of<E>(std::make_index_sequence<kKinds>{})>(params_)[n];
  }

 private:
  friend struct ForgeAccess;
  struct Entry {
    std::uint8_t kind = 0;
    std::uint8_t index = 0;
    std::uint16_t active_offset = 0;
    std::uint16_t value_offset = 0;
    bool stateful = true;  ///< its state can change: copied before it runs
  };
  static_assert(kActiveCapacity < 65536 && kValueCapacity < 65536);

  template <class E, std::size_t... I>
  static constexpr std::size_t index_of(std::index_sequence<I...>) noexcept {
    std::size_t found = kKinds;
    ((std::same_as<E, Kind<I>> ? void(found = I) : void()), ...);
    static_assert(((std::same_as<E, Kind<I>> ? 1 : 0) + ...) == 1, "not one of this scene's kinds");
    return found;
  }
  /// Calls `f.template operator()<I>(entry)` for the entry's kind.
  template <class F>
  static constexpr void dispatch(const Entry& e, F&& f) noexcept {
    dispatch_kinds(e, f, std::make_index_sequence<kKinds>{});
  }
  template <class F, std::size_t... I>
  static constexpr void dispatch_kinds(const Entry& e, F& f, std::index_sequence<I...>) noexcept {
    static_cast<void>(((e.kind == I ? (f.template operator()<I>(e), true) : false) || ...));
  }

  std::tuple<std::array<typename Kinds<S>::Params, effect::kMaxPerScene<Kinds<S>>>...> params_{};
  std::array<Entry, kMaxEffects> order_{};
  std::array<std::size_t, kKinds> counts_{};
  std::size_t effect_count_ = 0;
  std::size_t active_slots_ = 0;
  std::size_t value_count_ = 0;
  Needs needs_ = Needs::kNone;
};

/// The library's run-time scene: the built-in kinds (builtin.hpp: surfaces and cliffs), as
/// scene files describe them.
template <Scalar S>
using RuntimeScene = RuntimeSceneOf<S, TOONFORCE_BUILTIN_EFFECTS>;

}  // namespace toonforce
