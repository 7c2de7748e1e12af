#pragma once
/// Scenes: the sum of their effects' forces, in order (spec effects.md §0).
///
/// `Scene<Effects...>` is composed at compile time and contains only its effects: its state is
/// theirs, its `kNeeds` the union of theirs, so a stage no effect needs is compiled out.
/// `RuntimeScene<S>` holds what a scene file describes, in fixed capacity sized at start-up.
///
/// A scene's `force(in, state)` updates `state` in place; the caller keeps the previous state
/// when it must discard a tick (a non-finite force, spec §6.1), see control/controller.hpp.
/// An effect is a type with `Params`, `State`, `kNeeds` and
///   static Vec3<S> force(const Params&, State&, const TickInput<S>&) noexcept;
///   static void describe(const Params&, const State&, const TickInput<S>&, Diagnostics&) noexcept;

#include <array>
#include <concepts>
#include <cstddef>
#include <tuple>
#include <utility>

#include "toonforce/effects/cliff.hpp"
#include "toonforce/effects/surface.hpp"

namespace toonforce {

template <class E>
concept Effect = requires(const typename E::Params& p, typename E::State& s,
                          const TickInput<typename E::Scalar>& in, Diagnostics& d) {
  { E::force(p, s, in) } noexcept -> std::same_as<Vec3<typename E::Scalar>>;
  { E::describe(p, s, in, d) } noexcept;
  { E::kNeeds } -> std::convertible_to<Needs>;
};

/// What the controller needs of a scene, compile-time or run-time.
template <class T>
concept SceneType = requires(const T& scene, typename T::State& s, const typename T::State& cs,
                             const TickInput<typename T::Scalar>& in) {
  { scene.force(in, s) } noexcept -> std::same_as<Vec3<typename T::Scalar>>;
  { scene.needs() } noexcept -> std::same_as<Needs>;
  { scene.diagnostics(cs, in) } noexcept -> std::same_as<Diagnostics>;
  { scene.copy_state(cs, s) } noexcept;
  { T::kNeeds } -> std::convertible_to<Needs>;
};

template <Effect First, Effect... Rest>
class Scene {
 public:
  using Scalar = typename First::Scalar;
  static_assert((std::same_as<Scalar, typename Rest::Scalar> && ...), "one scalar per scene");
  using S = Scalar;
  using Params = std::tuple<typename First::Params, typename Rest::Params...>;
  struct State {
    std::tuple<typename First::State, typename Rest::State...> effects{};
  };
  static constexpr Needs kNeeds = (First::kNeeds | ... | Rest::kNeeds);

  constexpr explicit Scene(typename First::Params first, typename Rest::Params... rest) noexcept
      : params_{first, rest...} {}

  constexpr Vec3<S> force(const TickInput<S>& in, State& state) const noexcept {
    return sum(in, state, kIndices);
  }
  constexpr Needs needs() const noexcept { return kNeeds; }
  constexpr Diagnostics diagnostics(const State& state, const TickInput<S>& in) const noexcept {
    Diagnostics d;
    describe_all(state, in, d, kIndices);
    return d;
  }
  constexpr void copy_state(const State& from, State& to) const noexcept { to = from; }
  constexpr const Params& params() const noexcept { return params_; }

 private:
  using Effects = std::tuple<First, Rest...>;
  static constexpr auto kIndices = std::index_sequence_for<First, Rest...>{};

  template <std::size_t... I>
  constexpr Vec3<S> sum(const TickInput<S>& in, State& state, std::index_sequence<I...>) const noexcept {
    Vec3<S> total{};
    // The comma fold runs left to right: effects add in declaration order.
    ((total += std::tuple_element_t<I, Effects>::force(std::get<I>(params_), std::get<I>(state.effects), in)), ...);
    return total;
  }
  template <std::size_t... I>
  constexpr void describe_all(const State& state, const TickInput<S>& in, Diagnostics& d,
                              std::index_sequence<I...>) const noexcept {
    (std::tuple_element_t<I, Effects>::describe(std::get<I>(params_), std::get<I>(state.effects), in, d), ...);
  }

  Params params_;
};

/// The scene a file describes: any number of surfaces and cliffs up to a fixed capacity, each
/// surface with either tangential law and an optional impact, chosen at run time.
template <Scalar S>
class RuntimeScene {
 public:
  using Scalar = S;
  using SurfaceEffect = Surface<PenaltyWall<S>, AnyTangential<S>, MaybeImpact<S>>;
  using CliffEffect = CartoonCliff<S>;
  static constexpr std::size_t kMaxSurfaces = 16;
  static constexpr std::size_t kMaxCliffs = 8;
  static constexpr std::size_t kMaxEffects = kMaxSurfaces + kMaxCliffs;
  /// Upper bound of what a loaded scene may need; `needs()` says what this one needs.
  static constexpr Needs kNeeds = Needs::kVelocity;

  struct State {
    std::array<typename SurfaceEffect::State, kMaxSurfaces> surfaces{};
    std::array<typename CliffEffect::State, kMaxCliffs> cliffs{};
  };

  /// Appends a surface after the effects already added; false when full.
  constexpr bool add_surface(const typename SurfaceEffect::Params& p) noexcept {
    if (surface_count_ == kMaxSurfaces) return false;
    surfaces_[surface_count_] = p;
    order_[effect_count_++] = Entry{Kind::kSurface, static_cast<std::uint8_t>(surface_count_++)};
    const bool uses_velocity = p.wall.damping_n_s_per_m != S{} ||
                               p.tangential.kind != AnyTangential<S>::Kind::kNone || p.impact.enabled;
    if (uses_velocity) needs_ = needs_ | Needs::kVelocity;
    return true;
  }
  /// Appends a cliff after the effects already added; false when full.
  constexpr bool add_cliff(const typename CliffEffect::Params& p) noexcept {
    if (cliff_count_ == kMaxCliffs) return false;
    cliffs_[cliff_count_] = p;
    order_[effect_count_++] = Entry{Kind::kCliff, static_cast<std::uint8_t>(cliff_count_++)};
    needs_ = needs_ | CliffEffect::kNeeds;
    return true;
  }

  constexpr Vec3<S> force(const TickInput<S>& in, State& state) const noexcept {
    Vec3<S> total{};
    for (std::size_t i = 0; i < effect_count_; ++i) {
      const Entry e = order_[i];
      if (e.kind == Kind::kSurface) {
        total += SurfaceEffect::force(surfaces_[e.index], state.surfaces[e.index], in);
      } else {
        total += CliffEffect::force(cliffs_[e.index], state.cliffs[e.index], in);
      }
    }
    return total;
  }
  constexpr Needs needs() const noexcept { return needs_; }
  constexpr Diagnostics diagnostics(const State& state, const TickInput<S>& in) const noexcept {
    Diagnostics d;
    for (std::size_t i = 0; i < effect_count_; ++i) {
      const Entry e = order_[i];
      if (e.kind == Kind::kSurface) {
        SurfaceEffect::describe(surfaces_[e.index], state.surfaces[e.index], in, d);
      } else {
        CliffEffect::describe(cliffs_[e.index], state.cliffs[e.index], in, d);
      }
    }
    return d;
  }
  /// Copies only the slots in use, so a one-surface scene copies one state, not sixteen.
  constexpr void copy_state(const State& from, State& to) const noexcept {
    for (std::size_t i = 0; i < surface_count_; ++i) to.surfaces[i] = from.surfaces[i];
    for (std::size_t i = 0; i < cliff_count_; ++i) to.cliffs[i] = from.cliffs[i];
  }

  constexpr std::size_t surface_count() const noexcept { return surface_count_; }
  constexpr std::size_t cliff_count() const noexcept { return cliff_count_; }
  constexpr const typename SurfaceEffect::Params& surface(std::size_t i) const noexcept { return surfaces_[i]; }
  constexpr const typename CliffEffect::Params& cliff(std::size_t i) const noexcept { return cliffs_[i]; }

 private:
  enum class Kind : std::uint8_t { kSurface, kCliff };
  struct Entry {
    Kind kind = Kind::kSurface;
    std::uint8_t index = 0;
  };

  std::array<typename SurfaceEffect::Params, kMaxSurfaces> surfaces_{};
  std::array<typename CliffEffect::Params, kMaxCliffs> cliffs_{};
  std::array<Entry, kMaxEffects> order_{};
  std::size_t surface_count_ = 0;
  std::size_t cliff_count_ = 0;
  std::size_t effect_count_ = 0;
  Needs needs_ = Needs::kNone;
};

}  // namespace toonforce
