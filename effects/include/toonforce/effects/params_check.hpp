// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Parameters that come from outside the process: a live scene's update (docs/spec/
/// live-scenes.md) is written by another process, which may write anything. Before the servo
/// loop keeps an effect's parameters it checks them against what a scene file could have given:
/// the effect's schema (schema.hpp: every number finite and in its declared range, every unit
/// vector of unit length, every choice one of its names, every flag 0 or 1) and the effect's own
/// check() across keys. The ranges are the schema's, written once.
///
/// `effect::params_ok<E>(p)` is noexcept and allocates nothing. `p` may hold any bytes: a flag
/// or a choice is read through its bytes (a bool that is neither 0 nor 1 is never loaded as a
/// bool), before anything reads it as what it is.
///
/// An effect a live scene takes has a schema() (every library effect, and any a scene file can
/// name), or a `static bool valid(const Params&) noexcept` of its own; an effect with neither
/// does not compile into a live loop (the check cannot know its numbers). An effect may declare
/// both: valid() then adds to the schema's checks. Numbers in its Params outside its schema are
/// not seen: such an effect checks them in valid().

#include <cmath>
#include <cstddef>
#include <cstring>
#include <string_view>
#include <tuple>
#include <type_traits>

#include "toonforce/effects/effect.hpp"
#include "toonforce/effects/schema.hpp"
#include "toonforce/math/scalar_kind.hpp"

namespace toonforce {
namespace schema {

/// How far from 1 the squared length of a unit vector may be, as T holds it: a file's vector is
/// normalised in double, then rounded to T (Q16.16 rounds each component by up to 2^-17).
template <class T>
inline constexpr double kUnitTolerance = kIsFixed<T> ? 1e-4 : (std::is_same_v<T, float> ? 1e-5 : 1e-9);

namespace check_detail {

template <class T>
bool number_ok(const T& value, Range range) noexcept {
  const double v = to_double(value);
  return std::isfinite(v) && in_range(v, range);
}

/// The bytes of `member` as its underlying integer (no load of an invalid enum or bool).
template <class E>
auto bytes_of(const E& member) noexcept {
  if constexpr (std::is_enum_v<E>) {
    std::underlying_type_t<E> raw{};
    std::memcpy(&raw, &member, sizeof raw);
    return raw;
  } else {
    static_assert(std::is_same_v<E, bool>);
    unsigned char raw = 0;
    std::memcpy(&raw, &member, 1);
    return raw;
  }
}
template <class E>
bool same_bytes(const E& member, E value) noexcept {
  return bytes_of(member) == static_cast<std::underlying_type_t<E>>(value);
}

template <class P, class Fields>
bool fields_ok(const P& p, const Fields& fields) noexcept;

template <class P, class T>
bool field_ok(const P& p, const Number<P, T>& d) noexcept {
  return number_ok(p.*d.member, d.range);
}

template <class P, class T>
bool field_ok(const P& p, const Vector<P, T>& d) noexcept {
  const Vec3<T>& v = p.*d.member;
  const double x = to_double(v.x), y = to_double(v.y), z = to_double(v.z);
  if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) return false;
  if (!d.unit_length) return true;
  if constexpr (kIsFixed<T>) {  // a rounded unit component is within [-1, 1]
    if (!(std::fabs(x) <= 1.0 && std::fabs(y) <= 1.0 && std::fabs(z) <= 1.0)) return false;
  }
  return std::fabs(x * x + y * y + z * z - 1.0) <= kUnitTolerance<T>;
}

template <class P, class E, std::size_t N>
bool field_ok(const P& p, const Choice<P, E, N>& d) noexcept {
  bool known = same_bytes(p.*d.member, d.fallback);
  for (const auto& name : d.names) known = known || same_bytes(p.*d.member, name.second);
  return known;
}

template <class P, class M, class F>
bool field_ok(const P& p, const Inline<P, M, F>& d) noexcept {
  return fields_ok(p.*d.member, d.fields);
}

template <class P, class M, class F>
bool field_ok(const P& p, const Table<P, M, F>& d) noexcept {
  if (d.present == nullptr) return fields_ok(p.*d.member, d.fields);  // a required table
  const auto present = bytes_of(p.*d.present);
  if (present > 1) return false;
  return present == 0 || fields_ok(p.*d.member, d.fields);  // an absent table is not used
}

template <class P, class K, class... O>
bool field_ok(const P& p, const OneOf<P, K, O...>& d) noexcept {
  if (same_bytes(p.*d.kind, K{})) return true;  // none of them
  bool ok = false;
  std::apply(
      [&](const auto&... option) {
        static_cast<void>(
            ((same_bytes(p.*d.kind, option.value) ? (ok = fields_ok(p.*option.member, option.fields), true) : false) ||
             ...));
      },
      d.options);
  return ok;
}

template <class P, class Fields>
bool fields_ok(const P& p, const Fields& fields) noexcept {
  return std::apply([&](const auto&... d) { return (field_ok(p, d) && ...); }, fields);
}

/// An effect's check() reports here: only whether it found anything.
class Count final : public Problems {
 public:
  void add(std::string_view, std::string_view) noexcept override { ++count; }
  void add(std::string_view, std::string_view, double) noexcept override { ++count; }
  std::size_t count = 0;
};

}  // namespace check_detail
}  // namespace schema

namespace effect {

/// Whether E's parameters `p` (any bytes) are what a scene file could have given (see above).
template <Effect E>
bool params_ok(const typename E::Params& p) noexcept {
  constexpr bool kSchema = requires { E::schema(); };
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  constexpr bool kValid = requires { { E::valid(p) } noexcept -> std::convertible_to<bool>; };
  // clang-format on
  static_assert(kSchema || kValid,
                "an effect a live scene takes needs a schema() or a static bool valid(const Params&) noexcept");
  if constexpr (kSchema) {
    if (!schema::check_detail::fields_ok(p, E::schema())) return false;
  }
  if constexpr (kValid) {
    if (!E::valid(p)) return false;
  }
  // clang-format off
  if constexpr (requires(schema::Problems& problems) { E::check(p, problems, ScalarKind::kDouble); }) {
    // clang-format on
    schema::check_detail::Count problems;
    E::check(p, problems, scalar_kind_of<typename E::Scalar>());  // its flags and choices are checked above
    if (problems.count != 0) return false;
  }
  return true;
}

}  // namespace effect
}  // namespace toonforce
