// SPDX-License-Identifier: Apache-2.0
#pragma once
/// How an effect describes its scene-file table (spec interfaces.md "Scene files"), so that the
/// effect is written in one place and the scene-file reader, the run-time scene, the viewer and
/// the documentation take its keys from there: each key with its unit, range and default (or
/// "required"), and where it lands in the effect's `Params`.
///
/// An effect template `E<S>` declares `static constexpr auto schema()` returning `fields(...)`
/// of the descriptors below, written against its own `Params`. Because the same code is
/// instantiated for every scalar, `E<double>::schema()` and `E<S>::schema()` have the same
/// shape: a reader fills `E<double>::Params` (the values as written, checked in double) and
/// `convert_params` turns them into `E<S>::Params` field by field, so no effect keeps a double
/// mirror of its parameters anywhere else.
///
///   static constexpr auto schema() {
///     return schema::fields(
///         schema::number("stiffness", &Params::stiffness_n_per_m, "N/m", schema::Range::kPositive),
///         schema::number("damping", &Params::damping_n_s_per_m, "N s/m", schema::Range::kNonNegative, 0.0));
///   }
///
/// Checks that span several keys (a gap the wrong way round) are the effect's own
/// `static void check(const Params& in_double, schema::Problems&, ScalarKind)`.
/// Nothing here reads files or allocates: descriptors are constexpr aggregates of string views
/// and member pointers.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>

#include "toonforce/math/scalar_kind.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce::schema {

/// What a number must satisfy.
enum class Range : std::uint8_t { kAny, kPositive, kNonNegative, kNonPositive };

/// Whether `v` satisfies `range`: the one rule the scene-file reader and the loop's check of a
/// live update (params_check.hpp) both apply.
constexpr bool in_range(double v, Range range) noexcept {
  switch (range) {
    case Range::kPositive: return v > 0.0;
    case Range::kNonNegative: return v >= 0.0;
    case Range::kNonPositive: return v <= 0.0;
    case Range::kAny: break;
  }
  return true;
}

/// A number stored in a member of scalar type; required unless it has a default.
template <class P, class T>
struct Number {
  std::string_view key;
  T P::*member;
  std::string_view unit;  ///< "N/m"; empty for a pure number
  Range range = Range::kAny;
  bool required = true;
  double fallback = 0.0;       ///< the default when not required
  std::string_view hint = {};  ///< appended to a range error ("realistic friction opposes motion")
};

/// A 3-vector; `unit_length` ones are normalised on load (a zero vector is an error).
template <class P, class T>
struct Vector {
  std::string_view key;
  Vec3<T> P::*member;
  std::string_view unit;
  bool unit_length = false;
};

/// One of a few names, stored as an enum; optional with a default, or required.
template <class P, class E, std::size_t N>
struct Choice {
  std::string_view key;
  E P::*member;
  std::array<std::pair<std::string_view, E>, N> names;
  bool required = false;
  E fallback{};
};

/// The fields of a nested struct, written in the same table (a surface's plane and wall).
template <class P, class M, class Fields>
struct Inline {
  M P::*member;
  Fields fields;
};

/// An optional sub-table `[parent.key]`; `present` records whether the file has it.
template <class P, class M, class Fields>
struct Table {
  std::string_view key;
  M P::*member;
  bool P::*present;
  Fields fields;
};

/// One option of a OneOf: the sub-table `key` that selects `value`.
template <class P, class K, class M, class Fields>
struct Option {
  std::string_view key;
  K value;
  M P::*member;
  Fields fields;
};

/// At most one of several optional sub-tables; `kind` records which (its default when none).
/// `conflict` says why two of them cannot go together.
template <class P, class K, class... Options>
struct OneOf {
  K P::*kind;
  std::string_view conflict;
  std::tuple<Options...> options;
};

template <class... D>
constexpr std::tuple<D...> fields(D... d) noexcept {
  return {d...};
}

template <class P, class T>
constexpr Number<P, T> number(std::string_view key, T P::*member, std::string_view unit, Range range) noexcept {
  return {key, member, unit, range, true, 0.0, {}};
}
template <class P, class T>
constexpr Number<P, T> number(std::string_view key, T P::*member, std::string_view unit, Range range, double fallback,
                              std::string_view hint = {}) noexcept {
  return {key, member, unit, range, false, fallback, hint};
}
template <class P, class T>
constexpr Vector<P, T> vector(std::string_view key, Vec3<T> P::*member, std::string_view unit) noexcept {
  return {key, member, unit, false};
}
template <class P, class T>
constexpr Vector<P, T> unit_vector(std::string_view key, Vec3<T> P::*member) noexcept {
  return {key, member, "(unit after normalising)", true};
}
template <class P, class E, std::size_t N>
constexpr Choice<P, E, N> choice(std::string_view key, E P::*member,
                                 std::array<std::pair<std::string_view, E>, N> names, E fallback) noexcept {
  return {key, member, names, false, fallback};
}
template <class P, class M, class Fields>
constexpr Inline<P, M, Fields> inline_fields(M P::*member, Fields f) noexcept {
  return {member, f};
}
template <class P, class M, class Fields>
constexpr Table<P, M, Fields> table(std::string_view key, M P::*member, bool P::*present, Fields f) noexcept {
  return {key, member, present, f};
}
template <class P, class K, class M, class Fields>
constexpr Option<P, K, M, Fields> option(std::string_view key, K value, M P::*member, Fields f) noexcept {
  return {key, value, member, f};
}
template <class P, class K, class... O>
constexpr OneOf<P, K, O...> one_of(K P::*kind, std::string_view conflict, O... options) noexcept {
  return {kind, conflict, {options...}};
}

/// Where an effect's own checks report (the scene-file reader names file, line and key).
class Problems {
 public:
  /// `key` is one of the table's keys (its line is reported); `value` is printed after the text
  /// when given. The text is a literal: effects/ formats nothing.
  virtual void add(std::string_view key, std::string_view problem) = 0;
  virtual void add(std::string_view key, std::string_view problem, double value) = 0;

 protected:
  ~Problems() = default;
};

/// The problems of a sub-table, reported to the table's: key "sine" becomes "impact.sine".
class SubTableProblems final : public Problems {
 public:
  SubTableProblems(Problems& outer, std::string_view table) noexcept : outer_(outer), table_(table) {}
  void add(std::string_view key, std::string_view problem) override { outer_.add(join(key), problem); }
  void add(std::string_view key, std::string_view problem, double value) override {
    outer_.add(join(key), problem, value);
  }

 private:
  /// "table.key" in a buffer of its own (start-up code, but no allocation needed).
  std::string_view join(std::string_view key) noexcept {
    std::size_t n = 0;
    const auto put = [&](std::string_view part) {
      for (const char c : part) {
        if (n < sizeof buffer_) buffer_[n++] = c;
      }
    };
    put(table_);
    put(".");
    put(key);
    return {buffer_, n};
  }
  Problems& outer_;
  std::string_view table_;
  char buffer_[128]{};
};

/// An effect without checks of its own.
struct NoChecks {
  template <class P>
  static constexpr void check(const P&, Problems&, ScalarKind) noexcept {}
};

// ---- conversion from the double parameters a file gives to an effect's scalar ----------------

namespace detail {

template <class To, class From>
constexpr To convert_enum(From from) noexcept {
  if constexpr (std::is_same_v<To, From>) {
    return from;
  } else {
    return static_cast<To>(static_cast<std::underlying_type_t<From>>(from));
  }
}

template <class PD, class PS, class DD, class DS>
constexpr void convert_field(const PD& pd, PS& ps, const DD& d, const DS& s) noexcept;
template <class PD, class PS, class OD, class OS, std::size_t... I>
constexpr void convert_options(const PD& pd, PS& ps, const OD& od, const OS& os, std::index_sequence<I...>) noexcept;

template <class PD, class PS, class FD, class FS, std::size_t... I>
constexpr void convert_all(const PD& pd, PS& ps, const FD& fd, const FS& fs, std::index_sequence<I...>) noexcept {
  (convert_field(pd, ps, std::get<I>(fd), std::get<I>(fs)), ...);
}

template <class PD, class PS, class FD, class FS>
constexpr void convert_fields(const PD& pd, PS& ps, const FD& fd, const FS& fs) noexcept {
  static_assert(std::tuple_size_v<FD> == std::tuple_size_v<FS>, "one schema, instantiated twice");
  convert_all(pd, ps, fd, fs, std::make_index_sequence<std::tuple_size_v<FD>>{});
}

template <class T>
struct IsNumber : std::false_type {};
template <class P, class T>
struct IsNumber<Number<P, T>> : std::true_type {};
template <class T>
struct IsVector : std::false_type {};
template <class P, class T>
struct IsVector<Vector<P, T>> : std::true_type {};
template <class T>
struct IsChoice : std::false_type {};
template <class P, class E, std::size_t N>
struct IsChoice<Choice<P, E, N>> : std::true_type {};
template <class T>
struct IsInline : std::false_type {};
template <class P, class M, class F>
struct IsInline<Inline<P, M, F>> : std::true_type {};
template <class T>
struct IsTable : std::false_type {};
template <class P, class M, class F>
struct IsTable<Table<P, M, F>> : std::true_type {};
template <class T>
struct IsOneOf : std::false_type {};
template <class P, class K, class... O>
struct IsOneOf<OneOf<P, K, O...>> : std::true_type {};

template <class PD, class PS, class DD, class DS>
constexpr void convert_field(const PD& pd, PS& ps, const DD& d, const DS& s) noexcept {
  if constexpr (IsNumber<DD>::value) {
    using T = std::remove_cvref_t<decltype(ps.*s.member)>;
    ps.*s.member = scalar_cast<T>(static_cast<double>(pd.*d.member));
  } else if constexpr (IsVector<DD>::value) {
    using T = std::remove_cvref_t<decltype((ps.*s.member).x)>;
    const auto& v = pd.*d.member;
    ps.*s.member = Vec3<T>{scalar_cast<T>(static_cast<double>(v.x)), scalar_cast<T>(static_cast<double>(v.y)),
                           scalar_cast<T>(static_cast<double>(v.z))};
  } else if constexpr (IsChoice<DD>::value) {
    ps.*s.member = convert_enum<std::remove_cvref_t<decltype(ps.*s.member)>>(pd.*d.member);
  } else if constexpr (IsInline<DD>::value) {
    convert_fields(pd.*d.member, ps.*s.member, d.fields, s.fields);
  } else if constexpr (IsTable<DD>::value) {
    ps.*s.present = pd.*d.present;
    convert_fields(pd.*d.member, ps.*s.member, d.fields, s.fields);
  } else if constexpr (IsOneOf<DD>::value) {
    ps.*s.kind = convert_enum<std::remove_cvref_t<decltype(ps.*s.kind)>>(pd.*d.kind);
    convert_options(pd, ps, d.options, s.options,
                    std::make_index_sequence<std::tuple_size_v<std::remove_cvref_t<decltype(d.options)>>>{});
  } else {
    static_assert(sizeof(DD) == 0, "unknown schema descriptor");
  }
}

template <class PD, class PS, class OD, class OS, std::size_t... I>
constexpr void convert_options(const PD& pd, PS& ps, const OD& od, const OS& os, std::index_sequence<I...>) noexcept {
  ((convert_fields(pd.*std::get<I>(od).member, ps.*std::get<I>(os).member, std::get<I>(od).fields,
                   std::get<I>(os).fields)),
   ...);
}

}  // namespace detail

/// The parameters of `E<S>` from those of `E<double>` (read from a file and checked), converted
/// once at start-up with `scalar_cast` (round to nearest; the reader has checked every value
/// fits S).
template <class ED, class ES>
constexpr typename ES::Params convert_params(const typename ED::Params& in) noexcept {
  typename ES::Params out{};
  detail::convert_fields(in, out, ED::schema(), ES::schema());
  return out;
}

}  // namespace toonforce::schema
