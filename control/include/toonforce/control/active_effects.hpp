#pragma once
/// The active effects of a scene, one slot each: the effects that inject energy by design
/// (spec effects.md §3 super-slippery surface, §4 impact transient), with this tick's force and
/// whether an episode (a contact, a transient) is running, so the passivity controller can give
/// each episode its energy budget (spec §6).
///
/// `ActiveEffects<SceneT>` is a trait, specialised here for the run-time scene and for
/// compile-time scenes made of `Surface`s; any other scene has no active slots. It re-evaluates
/// the effect's own law on the state the controller just committed, with the same inputs, so
/// it reproduces exactly the force the effect added (the laws are pure; the impact's trigger
/// logic is idempotent for a repeated input: its previous penetration is now the current one,
/// so it cannot trigger twice). Slot order is fixed for the life of the scene.

#include <array>
#include <cstddef>
#include <tuple>
#include <utility>

#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// One active effect on one tick.
template <Scalar S>
struct ActiveForce {
  Vec3<S> force_n;          ///< what the effect added to the scene force this tick
  bool in_episode = false;  ///< it is acting: in contact (slippery) or a transient runs (impact)
  bool triggered = false;   ///< a new episode started this tick even if one was running (impact)
};

namespace detail {

/// The slippery part of a tangential law, or nothing.
template <Scalar S, class Tangential>
constexpr bool slippery_force(const typename Tangential::Params& p, const Contact<S>& c, const Vec3<S>& normal,
                              const TickInput<S>& in, Vec3<S>& out) noexcept {
  const Vec3<S> tangential_velocity = tangential_part(in.velocity_m_per_s, normal);
  if constexpr (std::same_as<Tangential, SuperSlippery<S>>) {
    if (!(c.penetration_m > S{})) return false;
    out = SuperSlippery<S>::force(p, tangential_velocity, S{});
    return true;
  } else if constexpr (std::same_as<Tangential, AnyTangential<S>>) {
    if (p.kind != AnyTangential<S>::Kind::kSlippery || !(c.penetration_m > S{})) return false;
    out = SuperSlippery<S>::force(p.slippery, tangential_velocity, S{});
    return true;
  } else {
    static_cast<void>(p);
    static_cast<void>(c);
    static_cast<void>(tangential_velocity);
    static_cast<void>(out);
    return false;
  }
}

template <class Impact>
inline constexpr bool kMayImpact = false;
template <Scalar S>
inline constexpr bool kMayImpact<ImpactTransient<S>> = true;
template <Scalar S>
inline constexpr bool kMayImpact<MaybeImpact<S>> = true;

/// The impact transient's force of this tick (from the committed state), or nothing.
template <Scalar S, class Impact>
constexpr void impact_force(const typename Impact::Params& p, const typename Impact::State& committed,
                            const Contact<S>& c, const Vec3<S>& normal, const TickInput<S>& in,
                            ActiveForce<S>& out) noexcept {
  if constexpr (kMayImpact<Impact>) {
    if constexpr (std::same_as<Impact, MaybeImpact<S>>) {
      if (!p.enabled) return;
    }
    if (!committed.running) return;
    typename Impact::State replay = committed;  // force() updates its state: work on a copy
    out.force_n = normal * Impact::force(p, replay, c, in);
    out.in_episode = replay.running;
    out.triggered = replay.running && committed.trigger.tick == in.now.tick;
  } else {
    static_cast<void>(p);
    static_cast<void>(committed);
    static_cast<void>(c);
    static_cast<void>(normal);
    static_cast<void>(in);
    static_cast<void>(out);
  }
}

template <class E>
struct SurfaceTraits {
  static constexpr bool kIsSurface = false;
};
template <class Wall, class Tangential, class Impact>
struct SurfaceTraits<Surface<Wall, Tangential, Impact>> {
  static constexpr bool kIsSurface = true;
  using T = Tangential;
  using I = Impact;
};

/// Two slots per surface: [0] its slippery law, [1] its impact transient.
template <class SurfaceE>
constexpr void surface_slots(const typename SurfaceE::Params& p, const typename SurfaceE::State& s,
                             const TickInput<typename SurfaceE::Scalar>& in,
                             ActiveForce<typename SurfaceE::Scalar>* out) noexcept {
  using S = typename SurfaceE::Scalar;
  using Traits = SurfaceTraits<SurfaceE>;
  const Contact<S> c = p.plane.contact(in);
  out[0] = {};
  out[1] = {};
  out[0].in_episode = slippery_force<S, typename Traits::T>(p.tangential, c, p.plane.normal, in, out[0].force_n);
  impact_force<S, typename Traits::I>(p.impact, s.impact, c, p.plane.normal, in, out[1]);
}

}  // namespace detail

/// No active slots: a scene the trait does not know.
template <class SceneT>
struct ActiveEffects {
  using S = typename SceneT::Scalar;
  static constexpr std::size_t kCapacity = 0;
  static constexpr std::size_t slots(const SceneT&) noexcept { return 0; }
  static constexpr void collect(const SceneT&, const typename SceneT::State&, const TickInput<S>&,
                                ActiveForce<S>*) noexcept {}
};

/// The run-time scene: slots 2i and 2i+1 belong to surface i.
template <Scalar S>
struct ActiveEffects<RuntimeScene<S>> {
  using SceneT = RuntimeScene<S>;
  static constexpr std::size_t kCapacity = 2 * SceneT::kMaxSurfaces;
  static constexpr std::size_t slots(const SceneT& scene) noexcept { return 2 * scene.surface_count(); }
  /// Writes `slots(scene)` entries.
  static constexpr void collect(const SceneT& scene, const typename SceneT::State& state, const TickInput<S>& in,
                                ActiveForce<S>* out) noexcept {
    for (std::size_t i = 0; i < scene.surface_count(); ++i) {
      detail::surface_slots<typename SceneT::SurfaceEffect>(scene.surface(i), state.surfaces[i], in, out + 2 * i);
    }
  }
};

/// A compile-time scene: slots 2i and 2i+1 belong to its i-th effect if that is a Surface.
template <Effect First, Effect... Rest>
struct ActiveEffects<Scene<First, Rest...>> {
  using SceneT = Scene<First, Rest...>;
  using S = typename SceneT::Scalar;
  static constexpr std::size_t kCapacity = 2 * (1 + sizeof...(Rest));
  static constexpr std::size_t slots(const SceneT&) noexcept { return kCapacity; }
  static constexpr void collect(const SceneT& scene, const typename SceneT::State& state, const TickInput<S>& in,
                                ActiveForce<S>* out) noexcept {
    collect_all(scene, state, in, out, std::index_sequence_for<First, Rest...>{});
  }

 private:
  template <std::size_t... I>
  static constexpr void collect_all(const SceneT& scene, const typename SceneT::State& state,
                                    const TickInput<S>& in, ActiveForce<S>* out, std::index_sequence<I...>) noexcept {
    (collect_one<I>(scene, state, in, out + 2 * I), ...);
  }
  template <std::size_t I>
  static constexpr void collect_one(const SceneT& scene, const typename SceneT::State& state,
                                    const TickInput<S>& in, ActiveForce<S>* out) noexcept {
    using E = std::tuple_element_t<I, std::tuple<First, Rest...>>;
    if constexpr (detail::SurfaceTraits<E>::kIsSurface) {
      detail::surface_slots<E>(std::get<I>(scene.params()), std::get<I>(state.effects), in, out);
    } else {
      out[0] = {};
      out[1] = {};
    }
  }
};

}  // namespace toonforce
