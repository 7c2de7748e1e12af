// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A surface (scene-file table `[[surface]]`): a plane rendered by a penalty wall, optionally
/// with one tangential law (realistic friction or the super-slippery surface, never both: they
/// contradict each other) and an impact transient. The contact geometry is computed once per
/// tick and shared by its laws; the friction's normal force N is the wall's force of the same
/// tick (spec effects.md §2).
///
///   using CartoonWall = Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>;
///
/// Active parts (spec §6, the passivity controller's slots), only those it has: the
/// super-slippery force while in contact, if the tangential law is the slippery one; then the
/// impact transient while it runs, if one is configured (active_slots()). Values shown in traces and the viewer: `contact` (0/1) and, with
/// an impact, `impact_t` (seconds since the running transient's trigger, NaN when none runs).

#include <array>

#include "toonforce/effects/friction.hpp"
#include "toonforce/effects/impact.hpp"
#include "toonforce/effects/penalty_wall.hpp"

namespace toonforce {

template <class Wall, class Tangential = NoTangential<typename Wall::Scalar>,
          class Impact = NoImpact<typename Wall::Scalar>, class PlaneT = Plane<typename Wall::Scalar>>
struct Surface {
  using Scalar = typename Wall::Scalar;
  using S = Scalar;
  struct Params {
    PlaneT plane;  ///< Plane, or an AxisPlane in a compiled Q-format scene
    typename Wall::Params wall{};
    [[no_unique_address]] typename Tangential::Params tangential{};
    [[no_unique_address]] typename Impact::Params impact{};
  };
  struct State {
    [[no_unique_address]] typename Impact::State impact{};
  };
  static constexpr std::string_view kKey = "surface";
  static constexpr std::size_t kMaxPerScene = 16;
  static constexpr Needs kNeeds = Wall::kNeeds | Tangential::kNeeds | Impact::kNeeds;
  static constexpr std::size_t kSlipperySlots = Tangential::kMayInject ? 1 : 0;
  static constexpr std::size_t kActiveSlots = kSlipperySlots + (Impact::kPresent ? 1 : 0);
  static constexpr auto kValues = [] {
    if constexpr (Impact::kPresent) {
      return std::array<ValueInfo, 2>{{{"contact", "", "the HIP penetrates the surface"},
                                       {"impact_t", "s", "time since the running impact's trigger (NaN: none)"}}};
    } else {
      return std::array<ValueInfo, 1>{{{"contact", "", "the HIP penetrates the surface"}}};
    }
  }();

  /// Scene-file keys: `point`, `normal`, the wall's, then the tangential law's table(s) and the
  /// impact's (spec interfaces.md).
  static constexpr auto schema() {
    using namespace schema;
    return fields(inline_fields(&Params::plane, PlaneT::schema()), inline_fields(&Params::wall, Wall::schema()),
                  part<Tangential>(&Params::tangential), part<Impact>(&Params::impact));
  }
  static void check(const Params& p, schema::Problems& problems, ScalarKind scalar) {
    if constexpr (requires { Impact::kTableKey; }) {  // a fixed law in its own sub-table
      schema::SubTableProblems sub(problems, Impact::kTableKey);
      Impact::check(p.impact, sub, scalar);
    } else if constexpr (requires { Impact::check(p.impact, problems, scalar); }) {
      Impact::check(p.impact, problems, scalar);
    }
  }
  /// A live scene's one-shot event (docs/spec/live-scenes.md): "impact" starts this
  /// surface's transient now as if the HIP had entered at `value` m/s (> 0), the law of spec
  /// effects.md §4 from t = 0 whether or not the HIP touches it; refused without an impact.
  static constexpr std::array<std::string_view, Impact::kPresent ? 1 : 0> kEvents = [] {
    if constexpr (Impact::kPresent) {
      return std::array<std::string_view, 1>{"impact"};
    } else {
      return std::array<std::string_view, 0>{};
    }
  }();
  static constexpr bool fire(const Params& p, State& s, std::size_t event, double value, Instant now) noexcept {
    if constexpr (Impact::kPresent) {
      if (event != 0 || !impact_configured(p.impact) || !(value > 0.0)) return false;
      return Impact::fire(p.impact, s.impact, value, now);
    } else {
      static_cast<void>(p);
      static_cast<void>(s);
      static_cast<void>(event);
      static_cast<void>(value);
      static_cast<void>(now);
      return false;
    }
  }

  /// Only an impact transient keeps state.
  static constexpr bool stateful(const Params& p) noexcept {
    if constexpr (Impact::kPresent) {
      return impact_configured(p.impact);
    } else {
      static_cast<void>(p);
      return false;
    }
  }
  /// What this surface needs: a spring-only wall without friction or impact needs no velocity.
  static constexpr Needs needs(const Params& p) noexcept {
    return Wall::needs(p.wall) | Tangential::needs(p.tangential) | Impact::needs(p.impact);
  }

  /// Active parts this surface has (the slippery law if it is the one, an impact if it is
  /// configured), reported in that order: a run-time scene gives each surface only these slots.
  static constexpr std::size_t active_slots(const Params& p) noexcept {
    std::size_t n = 0;
    if constexpr (Tangential::kMayInject) n += Tangential::injects(p.tangential) ? std::size_t{1} : std::size_t{0};
    if constexpr (Impact::kPresent) n += impact_configured(p.impact) ? std::size_t{1} : std::size_t{0};
    return n;
  }

  static constexpr Vec3<S> force(const Params& p, State& s, const TickInput<S>& in, ActiveForce<S>* active) noexcept {
    const Contact<S> c = p.plane.contact(in);
    const S wall_n = Wall::normal_force(p.wall, c);
    S along_normal = wall_n;
    ActiveForce<S>* next_slot = active;
    if constexpr (Tangential::kMayInject) {
      if (Tangential::injects(p.tangential)) ++next_slot;  // slot 0 is the slippery law's
    }
    if constexpr (Impact::kPresent) {
      const ImpactOutput<S> impact = Impact::force(p.impact, s.impact, c, in);
      along_normal += impact.force_n;
      if (impact_configured(p.impact)) *next_slot = {p.plane.along(impact.force_n), impact.running, impact.triggered};
    }
    // A unit normal times a push: without an impact the wall's, >= 0, which cannot saturate.
    Vec3<S> f = Impact::kPresent ? p.plane.along(along_normal) : p.plane.push(along_normal);
    if constexpr (Tangential::kPresent) {
      const bool touching = c.penetration_m > S{};
      Vec3<S> tangential{};
      if (touching && Tangential::present(p.tangential)) {
        // A Q format takes the contact's n.v; floating point computes it again, as
        // it did: with the contact's, GCC laid out the double runtime cartoon wall's tick (which
        // never runs this) 2 instructions dearer, past the 600-instruction budget.
        Vec3<S> v_t;
        if constexpr (kIsFixed<S>) {
          v_t = p.plane.tangential(in.velocity_m_per_s, c.normal_speed_m_per_s);
        } else {
          v_t = tangential_part(in.velocity_m_per_s, p.plane.normal);
        }
        tangential = Tangential::force(p.tangential, v_t, wall_n);
        f += tangential;
      }
      if constexpr (Tangential::kMayInject) {
        // Member by member: a brace-initialized copy of the 14-byte part became a memcpy call
        // on the Cortex-M3 built with -mno-unaligned-access, whose loop no bound covers.
        if (Tangential::injects(p.tangential)) {
          active[0].force_n = tangential;
          active[0].in_episode = touching;
          active[0].triggered = false;
        }
      }
    }
    return f;
  }

  /// The same without reporting the active parts (tests, callers without a passivity stage).
  static constexpr Vec3<S> force(const Params& p, State& s, const TickInput<S>& in) noexcept {
    ActiveForce<S> unused[kActiveSlots > 0 ? kActiveSlots : 1]{};
    return force(p, s, in, unused);
  }

  /// `contact` and, with an impact, `impact_t`; true while in contact.
  static constexpr bool describe(const Params& p, const State& s, const TickInput<S>& in, double* values) noexcept {
    const bool contact = p.plane.contact(in).penetration_m > S{};
    values[0] = contact ? 1.0 : 0.0;
    if constexpr (Impact::kPresent) values[1] = Impact::time_since_trigger(s.impact, in);
    return contact;
  }

 private:
  static constexpr bool impact_configured(const typename Impact::Params& p) noexcept {
    if constexpr (requires { p.enabled; }) {
      return p.enabled;
    } else {
      return true;
    }
  }
  /// A tangential law or an impact inside a surface: a sub-table of its own when the law is
  /// fixed (`[surface.impact]` of an ImpactTransient), its own keys when it chooses at run time.
  template <class Part, class M>
  static constexpr auto part(M Params::*member) {
    if constexpr (requires { Part::kTableKey; }) {
      return schema::table(Part::kTableKey, member, static_cast<bool Params::*>(nullptr), Part::schema());
    } else {
      return schema::inline_fields(member, Part::schema());
    }
  }
};

/// The surface a scene file describes: any wall, either tangential law or none, an optional
/// impact, all chosen by the file.
template <Scalar S>
using RuntimeSurface = Surface<PenaltyWall<S>, AnyTangential<S>, MaybeImpact<S>>;

}  // namespace toonforce
