// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What every force law sees on one servo tick (spec effects.md §0), and the geometry of the
/// HIP against a plane. Frame: the scene frame, SI units.

#include <cstdint>
#include <limits>
#include <string_view>
#include <type_traits>

#include "toonforce/effects/schema.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// Which shared per-tick stages a law needs; a scene's needs are the union of its laws', so a
/// stage nothing needs is compiled out (the velocity estimator of a spring-only scene).
enum class Needs : std::uint8_t {
  kNone = 0,
  kVelocity = 1,  ///< HIP velocity: estimated unless the device or the input supplies it
};
constexpr Needs operator|(Needs a, Needs b) noexcept {
  return static_cast<Needs>(static_cast<std::uint8_t>(a) | static_cast<std::uint8_t>(b));
}
constexpr bool has(Needs set, Needs need) noexcept {
  return (static_cast<std::uint8_t>(set) & static_cast<std::uint8_t>(need)) != 0;
}

/// When a tick happened, exact over any run length (spec §0: time is never accumulated in the
/// scalar type). The servo loop counts integer ticks on a fixed period (skipped ticks
/// included); replay carries each row's own time stamp, in whole nanoseconds (an integer, so
/// a fixed-point loop, which keeps its time in integers, needs no floating point for it).
struct Instant {
  std::int64_t tick = 0;      ///< ticks since the start of the run
  std::int64_t stamp_ns = 0;  ///< [ns] replay: the row's t; unused on a fixed period
};

inline constexpr std::int64_t kNsPerS = 1'000'000'000;

/// Seconds to the nearest whole nanosecond (a stamp or a period; |seconds| < 9.2e9).
constexpr std::int64_t ns_from_seconds(double seconds) noexcept {
  const double ns = seconds * static_cast<double>(kNsPerS);
  return static_cast<std::int64_t>(ns >= 0.0 ? ns + 0.5 : ns - 0.5);
}

/// Holds nothing: TickInput's nanosecond period in a floating-point loop (which times in double).
struct NoNanoseconds {};

/// The inputs of one tick, already in scalar S (converted once by the caller).
template <Scalar S>
struct TickInput {
  Vec3<S> position_m;        ///< HIP position [m]
  Vec3<S> velocity_m_per_s;  ///< HIP velocity [m/s] (zero when the scene needs none)
  /// 1/dt [Hz], dt being the true time since the previous tick. The laws are written with the
  /// rate, not the period, because integer servo rates are exact in a Q format and their
  /// periods are not (1 ms is 65.536 counts of Q16.16).
  S rate_hz;
  Instant now;
  /// [s] > 0: ticks are this far apart and times are (k - k0) * period; 0: use the stamps.
  double period_s = 0.0;
  /// A fixed-point S: the period in whole nanoseconds (0: use the stamps), so that the laws'
  /// times are integers (`ns_since`) and a Q build links no floating point (tools/mcu).
  [[no_unique_address]] std::conditional_t<kIsFixed<S>, std::int64_t, NoNanoseconds> period_ns{};

  /// Seconds from `earlier` to this tick, in double (spec §0: "(k - k_trigger) * T, in
  /// double, converted once"; replay: "t_row - t_trigger").
  constexpr double seconds_since(Instant earlier) const noexcept {
    return period_s > 0.0 ? static_cast<double>(now.tick - earlier.tick) * period_s
                          : static_cast<double>(now.stamp_ns - earlier.stamp_ns) / static_cast<double>(kNsPerS);
  }
  /// A fixed-point S: nanoseconds from `earlier` to this tick, in integers.
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  constexpr std::int64_t ns_since(Instant earlier) const noexcept
    requires kIsFixed<S>
  {
    // clang-format on
    return period_ns > 0 ? (now.tick - earlier.tick) * period_ns : now.stamp_ns - earlier.stamp_ns;
  }
};

/// The HIP against one plane on one tick.
template <Scalar S>
struct Contact {
  S penetration_m;         ///< delta = -n.(x - p0); in contact when > 0
  S normal_speed_m_per_s;  ///< n.v (negative while moving into the solid)
};

/// A plane with a point and a unit normal pointing out of the solid (spec §0).
template <Scalar S>
struct Plane {
  Vec3<S> point_m;
  Vec3<S> normal;  ///< unit length (normalised when the scene is loaded)

  constexpr Contact<S> contact(const TickInput<S>& in) const noexcept {
    return {-dot_unit_difference(normal, in.position_m, point_m), dot_unit(normal, in.velocity_m_per_s)};
  }
  /// n k for a push k >= 0 (times_in_range).
  constexpr Vec3<S> push(S k) const noexcept { return times_in_range(normal, k); }
  /// n k for any k (times_unit).
  constexpr Vec3<S> along(S k) const noexcept { return times_unit(normal, k); }
  /// v's part in the plane, v - (n.v) n, with n.v known (tangential_part).
  constexpr Vec3<S> tangential(const Vec3<S>& v, S n_dot_v) const noexcept {
    return tangential_part(v, normal, n_dot_v);
  }

  /// Scene-file keys `point` [m] and `normal` (normalised on load; zero is an error).
  static constexpr auto schema() {
    return schema::fields(schema::vector("point", &Plane::point_m, "m"), schema::unit_vector("normal", &Plane::normal));
  }
};

/// A Plane whose normal is the coordinate axis `kAxis` (0 x, 1 y, 2 z) times `kSign` (+1 or -1),
/// known at compile time: what a compiled Q-format scene uses for such a plane (tools/mcu's
/// generator picks it when a file's normal is exactly an axis; every paper scene's is). Each
/// product with the normal is then a copy or a negation of one component, not three 64-bit
/// products (a slippery surface's tick took six for its contact and three for each
/// vector along or across the normal). Every result is bit for bit Plane's with that normal
/// (raw +-2^F on the axis, 0 elsewhere), saturations and their flag included:
/// tests/effects_test.cpp compares them on edge and random values, and surfaces on both.
template <Scalar S, int kAxis, int kSign>
struct AxisPlane {
  static_assert(kIsFixed<S>, "floating point keeps Plane: its products with 0 and 1 are not all copies (-0, NaN)");
  static_assert(kAxis >= 0 && kAxis <= 2 && (kSign == 1 || kSign == -1));
  using Raw = typename S::Raw;
  using Wide = typename S::Wide;
  Vec3<S> point_m;

  static constexpr Vec3<S> normal_of() noexcept {
    Vec3<S> n{};
    component(n) = S::from_raw(static_cast<Raw>(kSign * S::kOneRaw));
    return n;
  }
  // Named as Plane's field, which the code generic over both reads as `plane.normal`.
  static constexpr Vec3<S> normal = normal_of();  // NOLINT(readability-identifier-naming)

  // n.(x - p) is kSign (x_a - p_a) 2^F before Plane's rounding, which leaves kSign (x_a - p_a)
  // exactly: from_wide of it saturates as from_product did. n.v likewise.
  constexpr Contact<S> contact(const TickInput<S>& in) const noexcept {
    const Wide difference = Wide{component(in.position_m).raw()} - component(point_m).raw();
    return {-S::from_wide(kSign * difference), S::from_wide(kSign * Wide{component(in.velocity_m_per_s).raw()})};
  }
  // Plane's product of a component of +-1 and k rounds to +-k exactly, cast to Raw as
  // times_in_range casts it (so -k of lowest() wraps there as here); of 0, to 0.
  constexpr Vec3<S> push(S k) const noexcept {
    Vec3<S> v{};
    component(v) = S::from_raw(static_cast<Raw>(kSign * Wide{k.raw()}));
    return v;
  }
  constexpr Vec3<S> along(S k) const noexcept { return push(max(k, -S::max())); }
  // v - along(n.v): the other components less 0 are themselves.
  constexpr Vec3<S> tangential(const Vec3<S>& v, S n_dot_v) const noexcept {
    Vec3<S> t = v;
    component(t) = component(v) - component(along(n_dot_v));
    return t;
  }

 private:
  /// The axis's component of a vector (const or not, or a temporary read in the same expression).
  template <class V>
  static constexpr auto& component(V&& v) noexcept {
    if constexpr (kAxis == 0) {
      return v.x;
    } else if constexpr (kAxis == 1) {
      return v.y;
    } else {
      return v.z;
    }
  }
};

/// What an active part of an effect (one that injects energy by design: the super-slippery
/// surface, the impact transient) added to the scene force on one tick, so the passivity
/// controller can hold each of its episodes (a contact, a transient) to an energy budget
/// (spec effects.md §6). An effect declares how many such parts it has (`kActiveSlots`) and
/// reports each of them on every tick.
template <Scalar S>
struct ActiveForce {
  Vec3<S> force_n;          ///< what the part added to the scene force this tick [N]
  bool in_episode = false;  ///< it is acting: in contact (slippery) or a transient runs (impact)
  bool triggered = false;   ///< a new episode started this tick even if one was running (impact)
};

/// One value an effect shows in traces, telemetry and the viewer (its diagnostic state).
struct ValueInfo {
  std::string_view name;  ///< column suffix: "impact_t" becomes "surface1.impact_t"
  std::string_view unit;  ///< "s", "m/s", "" for flags and states
  std::string_view doc;
};

}  // namespace toonforce
