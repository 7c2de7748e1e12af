#pragma once
/// A surface: a plane rendered by a penalty wall, optionally with one tangential law (realistic
/// friction or the super-slippery surface, never both: they contradict each other) and an
/// impact transient. The contact geometry is computed once per tick and shared by its laws;
/// the friction's normal force N is the wall's force of the same tick (spec effects.md §2).
///
///   using CartoonWall = Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>;

#include "toonforce/effects/friction.hpp"
#include "toonforce/effects/impact.hpp"
#include "toonforce/effects/penalty_wall.hpp"

namespace toonforce {

template <class Wall, class Tangential = NoTangential<typename Wall::Scalar>,
          class Impact = NoImpact<typename Wall::Scalar>>
struct Surface {
  using Scalar = typename Wall::Scalar;
  using S = Scalar;
  struct Params {
    Plane<S> plane;
    typename Wall::Params wall{};
    [[no_unique_address]] typename Tangential::Params tangential{};
    [[no_unique_address]] typename Impact::Params impact{};
  };
  struct State {
    [[no_unique_address]] typename Impact::State impact{};
  };
  static constexpr Needs kNeeds = Wall::kNeeds | Tangential::kNeeds | Impact::kNeeds;

  static constexpr Vec3<S> force(const Params& p, State& s, const TickInput<S>& in) noexcept {
    const Contact<S> c = p.plane.contact(in);
    const S wall_n = Wall::normal_force(p.wall, c);
    S along_normal = wall_n;
    if constexpr (Impact::kActive) along_normal += Impact::force(p.impact, s.impact, c, in);
    Vec3<S> f = p.plane.normal * along_normal;
    if constexpr (Tangential::kActive) {
      if (c.penetration_m > S{}) {
        f += Tangential::force(p.tangential, tangential_part(in.velocity_m_per_s, p.plane.normal), wall_n);
      }
    }
    return f;
  }

  static constexpr void describe(const Params& p, const State& s, const TickInput<S>& in,
                                 Diagnostics& d) noexcept {
    if (p.plane.contact(in).penetration_m > S{}) d.in_contact = true;
    if constexpr (Impact::kActive) {
      const double t = Impact::time_since_trigger(s.impact, in);
      if (t == t && !(d.impact_time_s == d.impact_time_s)) d.impact_time_s = t;  // first running one
    }
  }
};

}  // namespace toonforce
