// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Tangential laws of a surface, applied only while the HIP is in contact and added to the
/// wall force (spec effects.md §2-3). Each takes the tangential velocity v_t = v - (n.v) n and
/// the wall's normal force N of the same tick.

#include <algorithm>

#include "toonforce/effects/tick.hpp"

namespace toonforce {

/// No tangential force: a frictionless surface.
template <Scalar S>
struct NoTangential {
  struct Params {};
  static constexpr Needs kNeeds = Needs::kNone;
  static constexpr bool kPresent = false;
  static constexpr bool kMayInject = false;
  static constexpr auto schema() { return schema::fields(); }
  static constexpr Needs needs(const Params&) noexcept { return Needs::kNone; }
  static constexpr bool injects(const Params&) noexcept { return false; }
  static constexpr bool present(const Params&) noexcept { return false; }
  static constexpr Vec3<S> force(const Params&, const Vec3<S>&, S) noexcept { return {}; }
};

/// Realistic friction (paper §4.1 eqs. 1-2; spec §2), both parts add:
///   viscous:  F_t = mu_v v_t, mu_v <= 0;
///   Coulomb:  F_t = -mu_c N v_t / max(|v_t|, v_reg).
/// Below v_reg the Coulomb part is a damper of mu_c N / v_reg, continuous through v_t = 0; too
/// small a v_reg makes that damper more than a sampled loop renders (it buzzes), hence the
/// 0.02 m/s default.
template <Scalar S>
struct RealisticFriction {
  struct Params {
    S viscous_n_s_per_m{};             ///< mu_v [N s/m], <= 0 (default 0)
    S coulomb{};                       ///< mu_c [-], >= 0 (default 0)
    S regularization_speed_m_per_s{};  ///< v_reg [m/s], > 0 (default 0.02)
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kPresent = true;
  static constexpr bool kMayInject = false;  // it opposes motion: passive
  static constexpr std::string_view kTableKey = "friction";

  /// Scene-file table `friction`: `viscous` [N s/m, default 0, <= 0], `coulomb` [-, default 0,
  /// >= 0], `regularization_speed` [m/s, default 0.02, > 0].
  static constexpr auto schema() {
    using namespace schema;
    return fields(
        number("viscous", &Params::viscous_n_s_per_m, "N s/m", Range::kNonPositive, 0.0,
               "realistic viscous friction opposes motion; for mu > 0 use a [surface.slippery] table instead"),
        number("coulomb", &Params::coulomb, "", Range::kNonNegative, 0.0),
        number("regularization_speed", &Params::regularization_speed_m_per_s, "m/s", Range::kPositive, 0.02));
  }
  static constexpr Needs needs(const Params&) noexcept { return Needs::kVelocity; }
  static constexpr bool injects(const Params&) noexcept { return false; }
  static constexpr bool present(const Params&) noexcept { return true; }

  static constexpr Vec3<S> force(const Params& p, const Vec3<S>& tangential_velocity, S normal_force_n) noexcept {
    if constexpr (kIsFixed<S>) {
      // mu_c N / max(|v_t|, v_reg) from the inverse root of the larger exact square: no root
      // and no division (they were about 140 instructions and four UDIVs of the
      // Cortex-M3 tick's bound), and no rounding of the speed (v_reg = 0.02 m/s is 1,311 LSB:
      // a rounded speed was 4e-4 off, the gain now within 2^-26 and half an LSB).
      const S push = p.coulomb * normal_force_n;  // [N], >= 0 in a scene file: mu_c >= 0, N >= 0
      const std::uint64_t squares =
          std::max(detail::raw_squares(tangential_velocity), detail::raw_square(p.regularization_speed_m_per_s));
      S coulomb_gain{};  // [N s/m]; with v_t = 0 (and a v_reg of 0, which a file cannot give) any gain gives 0
      if (squares != 0) {
        const auto magnitude = static_cast<std::uint32_t>(push.raw() < 0 ? 0U - static_cast<std::uint32_t>(push.raw())
                                                                         : static_cast<std::uint32_t>(push.raw()));
        const auto gain =
            static_cast<typename S::Wide>(detail::over_root<S::kFracBits>(magnitude, detail::inverse_root(squares)));
        coulomb_gain = S::from_wide(push.raw() < 0 ? -gain : gain);
      }
      return tangential_velocity * (p.viscous_n_s_per_m - coulomb_gain);
    } else {
      const S speed = max(norm(tangential_velocity), p.regularization_speed_m_per_s);
      const S coulomb_gain = p.coulomb * normal_force_n / speed;  // [N s/m]
      return tangential_velocity * (p.viscous_n_s_per_m - coulomb_gain);
    }
  }
};

/// The cartoon super-slippery surface (paper §4.1 eq. 3; spec §3): F_t = mu v_t with mu > 0,
/// pushing along the motion, scaled down (direction kept) to at most max_tangential_force. It
/// injects energy by design; the safety stage bounds what reaches the device.
template <Scalar S>
struct SuperSlippery {
  struct Params {
    S mu_n_s_per_m{};            ///< mu [N s/m], > 0 (scene key `mu`, required)
    S max_tangential_force_n{};  ///< [N], > 0 (default 2)
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kPresent = true;
  static constexpr bool kMayInject = true;  // pushes along the motion: an active part
  static constexpr std::string_view kTableKey = "slippery";

  /// Scene-file table `slippery`: `mu` [N s/m, required, > 0], `max_tangential_force` [N,
  /// default 2, > 0].
  static constexpr auto schema() {
    using namespace schema;
    return fields(number("mu", &Params::mu_n_s_per_m, "N s/m", Range::kPositive),
                  number("max_tangential_force", &Params::max_tangential_force_n, "N", Range::kPositive, 2.0));
  }
  static constexpr Needs needs(const Params&) noexcept { return Needs::kVelocity; }
  static constexpr bool injects(const Params&) noexcept { return true; }
  static constexpr bool present(const Params&) noexcept { return true; }

  static constexpr Vec3<S> force(const Params& p, const Vec3<S>& tangential_velocity, S /*normal_force_n*/) noexcept {
    return limit_magnitude(tangential_velocity * p.mu_n_s_per_m, p.max_tangential_force_n);
  }
};

/// Which tangential law a run-time surface has.
enum class TangentialKind : std::uint8_t { kNone, kFriction, kSlippery };

/// Either tangential law or none, chosen at run time (scenes loaded from files).
template <Scalar S>
struct AnyTangential {
  using Kind = TangentialKind;
  struct Params {
    Kind kind = Kind::kNone;
    typename RealisticFriction<S>::Params friction{};
    typename SuperSlippery<S>::Params slippery{};
  };
  static constexpr Needs kNeeds = Needs::kVelocity;
  static constexpr bool kPresent = true;
  static constexpr bool kMayInject = true;  // when it is the slippery one

  /// Scene-file tables `friction` or `slippery`, at most one of them (spec interfaces.md).
  static constexpr auto schema() {
    using namespace schema;
    return fields(one_of(
        &Params::kind,
        "they contradict each other (friction opposes motion, the slippery surface pushes along "
        "it); keep one",
        option(RealisticFriction<S>::kTableKey, Kind::kFriction, &Params::friction, RealisticFriction<S>::schema()),
        option(SuperSlippery<S>::kTableKey, Kind::kSlippery, &Params::slippery, SuperSlippery<S>::schema())));
  }
  static constexpr Needs needs(const Params& p) noexcept {
    return p.kind == Kind::kNone ? Needs::kNone : Needs::kVelocity;
  }
  static constexpr bool injects(const Params& p) noexcept { return p.kind == Kind::kSlippery; }
  static constexpr bool present(const Params& p) noexcept { return p.kind != Kind::kNone; }

  static constexpr Vec3<S> force(const Params& p, const Vec3<S>& tangential_velocity, S normal_force_n) noexcept {
    switch (p.kind) {
      case Kind::kFriction: return RealisticFriction<S>::force(p.friction, tangential_velocity, normal_force_n);
      case Kind::kSlippery: return SuperSlippery<S>::force(p.slippery, tangential_velocity, normal_force_n);
      case Kind::kNone: break;
    }
    return {};
  }
};

}  // namespace toonforce
