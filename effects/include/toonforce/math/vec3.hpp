// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A 3-vector in the scene frame (spec effects.md §0: x right, y away from the user, z up;
/// SI units). For Q types, dot products and norms accumulate raw products in 64 bits and round
/// once, so a norm is never built from saturated squares (spec §7).

#include <cstdint>
#include <optional>
#include <type_traits>

#include "toonforce/math/scalar.hpp"

namespace toonforce {

template <Scalar S>
struct Vec3 {
  S x{};
  S y{};
  S z{};

  friend constexpr Vec3 operator+(const Vec3& a, const Vec3& b) noexcept { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend constexpr Vec3 operator-(const Vec3& a, const Vec3& b) noexcept { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend constexpr Vec3 operator-(const Vec3& a) noexcept { return {-a.x, -a.y, -a.z}; }
  friend constexpr Vec3 operator*(const Vec3& a, S k) noexcept { return {a.x * k, a.y * k, a.z * k}; }
  friend constexpr Vec3 operator*(S k, const Vec3& a) noexcept { return {k * a.x, k * a.y, k * a.z}; }
  constexpr Vec3& operator+=(const Vec3& o) noexcept { return *this = *this + o; }
  constexpr Vec3& operator-=(const Vec3& o) noexcept { return *this = *this - o; }
  friend constexpr bool operator==(const Vec3&, const Vec3&) noexcept = default;
};

/// Converts a double vector (scene files, device readings) into scalar S, once.
template <Scalar S>
constexpr Vec3<S> vec_cast(const Vec3<double>& v) noexcept {
  return {scalar_cast<S>(v.x), scalar_cast<S>(v.y), scalar_cast<S>(v.z)};
}
template <Scalar S>
constexpr Vec3<double> to_double(const Vec3<S>& v) noexcept {
  return {to_double(v.x), to_double(v.y), to_double(v.z)};
}

template <Scalar S>
constexpr S dot(const Vec3<S>& a, const Vec3<S>& b) noexcept {
  if constexpr (kIsFixed<S>) {
    using W = typename S::Wide;
    const W px = W{a.x.raw()} * b.x.raw();
    const W py = W{a.y.raw()} * b.y.raw();
    const W pz = W{a.z.raw()} * b.z.raw();
    // Each product fits in 63 bits; their sum may not, and overflowing it can only mean a
    // result far outside the Q range, so it saturates (toward the sign that overflowed).
    W partial = 0;
    if (__builtin_add_overflow(px, py, &partial)) return S::from_wide(px > 0 ? INT64_MAX : INT64_MIN);
    W sum = 0;
    if (__builtin_add_overflow(partial, pz, &sum)) return S::from_wide(pz > 0 ? INT64_MAX : INT64_MIN);
    return S::from_wide(S::round_shift(sum, S::kFracBits));
  } else {
    return a.x * b.x + a.y * b.y + a.z * b.z;
  }
}

namespace detail {
/// n.v of a Q-format unit vector n, exact in raw units of 2^-2F: each raw product below 2^47,
/// their sum below 2^49, so no overflow test is needed.
template <Scalar S>
constexpr typename S::Wide raw_dot_unit(const Vec3<S>& n, const Vec3<S>& v) noexcept {
  using W = typename S::Wide;
  return W{n.x.raw()} * v.x.raw() + W{n.y.raw()} * v.y.raw() + W{n.z.raw()} * v.z.raw();
}
}  // namespace detail

/// n.v for a unit vector n (each component in [-1, 1]: a plane's normal, an axis): what dot()
/// gives, without its overflow tests (a plane's contact takes two such products a tick).
template <Scalar S>
constexpr S dot_unit(const Vec3<S>& n, const Vec3<S>& v) noexcept {
  if constexpr (kIsFixed<S>) {
    return S::from_product(detail::raw_dot_unit(n, v));
  } else {
    return dot(n, v);
  }
}
/// n.(v - p) for a unit vector n. In a Q format n.v - n.p is summed exactly, then rounded once:
/// what dot(n, v - p) gives unless a component of v - p saturates (a point 32,768 m away),
/// which here does not happen first.
template <Scalar S>
constexpr S dot_unit_difference(const Vec3<S>& n, const Vec3<S>& v, const Vec3<S>& p) noexcept {
  if constexpr (kIsFixed<S>) {
    return S::from_product(detail::raw_dot_unit(n, v) - detail::raw_dot_unit(n, p));  // below 2^50
  } else {
    return dot(n, v - p);
  }
}

/// A norm and what scaling to it divides by. In a Q format the norm of a vector whose
/// components are near the largest value exceeds it (up to sqrt(3) times) and `value`
/// saturates; `root` is the true norm in raw units (< 2^32), so a scaling divides by it and
/// never takes the root again.
template <Scalar S>
struct NormOf {
  S value;
  std::conditional_t<kIsFixed<S>, std::uint32_t, S> root;
};

namespace detail {
/// |v|^2 of a Q-format vector, exact: its raw squares in unsigned 64 bits (each <= 2^62, three
/// of them < 2^64), in units of 2^-2F. Each square is a signed product (it fits: at most 2^62)
/// taken as unsigned, so the sum is a signed multiply-accumulate (SMLAL) with no |r| first
/// (two instructions a component, five sums a tick).
template <Scalar S>
constexpr std::uint64_t raw_squares(const Vec3<S>& v) noexcept {
  const auto sq = [](typename S::Raw r) {
    const auto m = static_cast<std::int64_t>(r);
    return static_cast<std::uint64_t>(m * m);
  };
  return sq(v.x.raw()) + sq(v.y.raw()) + sq(v.z.raw());
}
/// limit^2 in the units of raw_squares, exact (a negative limit counts as 0).
template <Scalar S>
constexpr std::uint64_t raw_square(S limit) noexcept {
  const auto m = static_cast<std::uint64_t>(limit.raw() < 0 ? 0 : limit.raw());
  return m * m;
}
/// The norm whose exact square is `squares` (raw_squares): the root of a value in units of
/// 2^-2F is the norm in units of 2^-F, which is the raw result (<= sqrt(3) 2^31 < 2^32).
template <Scalar S>
constexpr NormOf<S> norm_from_raw_squares(std::uint64_t squares) noexcept {
  const std::uint64_t root = isqrt_round(squares);
  return {S::from_wide(static_cast<std::int64_t>(root)), static_cast<std::uint32_t>(root)};
}
}  // namespace detail

template <Scalar S>
constexpr NormOf<S> norm_of(const Vec3<S>& v) noexcept {
  if constexpr (kIsFixed<S>) {
    return detail::norm_from_raw_squares<S>(detail::raw_squares(v));
  } else {
    const S n = sqrt(dot(v, v));
    return {n, n};
  }
}

template <Scalar S>
constexpr S norm(const Vec3<S>& v) noexcept {
  return norm_of(v).value;
}

/// A limit's square, computed once for a limit that does not change (exact in a Q format: raw,
/// in the units of its raw squares).
template <Scalar S>
struct SquaredLimit {
  std::conditional_t<kIsFixed<S>, std::uint64_t, S> value{};
};
template <Scalar S>
constexpr SquaredLimit<S> squared_limit(double limit) noexcept {
  if constexpr (kIsFixed<S>) {
    return {detail::raw_square(scalar_cast<S>(limit))};
  } else {
    return {scalar_cast<S>(limit * limit)};  // squared in double, then rounded once
  }
}
/// Whether |v| exceeds the limit, as its square (exactly in a Q format, as norm_if_above).
template <Scalar S>
constexpr bool norm_exceeds(const Vec3<S>& v, SquaredLimit<S> limit) noexcept {
  if constexpr (kIsFixed<S>) {
    return detail::raw_squares(v) > limit.value;
  } else {
    return dot(v, v) > limit.value;
  }
}

/// Whether |v| is below the limit, as its square (exactly in a Q format).
template <Scalar S>
constexpr bool norm_below(const Vec3<S>& v, SquaredLimit<S> limit) noexcept {
  if constexpr (kIsFixed<S>) {
    return detail::raw_squares(v) < limit.value;
  } else {
    return dot(v, v) < limit.value;
  }
}

/// |v| when it exceeds `limit` (>= 0), else nothing: the test of every magnitude limit, with
/// the norm (a square root) only when the limit bites. In a Q format the squares are compared
/// exactly, raw in 64 bits. Compared as Q16.16 values they were rounded to 2^-16: a 0.02 N
/// step's square is 26 LSB, so steps up to 0.5 % over a 0.02 N rate limit passed it (38 % over
/// a 0.002 N one), and squares above 32,768 saturated, so a clamp above 181 N never bit.
template <Scalar S>
constexpr std::optional<NormOf<S>> norm_if_above(const Vec3<S>& v, S limit) noexcept {
  if constexpr (kIsFixed<S>) {
    const std::uint64_t squares = detail::raw_squares(v);
    if (squares <= detail::raw_square(limit)) return std::nullopt;
    return detail::norm_from_raw_squares<S>(squares);
  } else {
    if (!(dot(v, v) > limit * limit)) return std::nullopt;
    const NormOf<S> magnitude = norm_of(v);
    if (!(magnitude.value > limit)) return std::nullopt;
    return magnitude;
  }
}

template <Scalar S>
constexpr bool is_finite(const Vec3<S>& v) noexcept {
  if constexpr (kIsFixed<S>) {
    return is_finite(v.x) && is_finite(v.y) && is_finite(v.z);
  } else {
    // x - x is +0 for a finite x and NaN for an infinite or NaN one, so the sum below is 0 or
    // NaN: one test with no branch per component (the build has no fast-math, so the compiler
    // keeps x - x). Every servo tick checks the handle's position this way.
    const S zero = (v.x - v.x) + (v.y - v.y) + (v.z - v.z);
    return zero == zero;
  }
}

namespace detail {
/// Each component of a Q-format `v` times a fraction `factor` in units of 2^-32 (below 1), as
/// |c| times it rounded to nearest with the sign put back: nothing can saturate, and no
/// division per component (the tick's static bound counts each one).
template <Scalar S>
constexpr Vec3<S> scaled_by_fraction(const Vec3<S>& v, std::uint32_t factor) noexcept {
  using Raw = typename S::Raw;
  make_opaque(factor);  // capped from a 64-bit quotient: GCC would multiply its high word too
  const auto scale = [factor](S c) {
    const auto sign = static_cast<std::uint32_t>(c.raw() >> 31);                  // all ones when negative
    const std::uint32_t m = (static_cast<std::uint32_t>(c.raw()) ^ sign) - sign;  // |c| <= 2^31
    // (p + 2^31) >> 32 without a 64-bit sum: the high word plus the low word's top bit.
    const std::uint64_t p = std::uint64_t{m} * factor;
    const auto scaled = static_cast<std::uint32_t>(p >> 32) + (static_cast<std::uint32_t>(p) >> 31);  // <= |c|
    return S::from_raw(static_cast<Raw>((scaled ^ sign) - sign));
  };
  return {scale(v.x), scale(v.y), scale(v.z)};
}
}  // namespace detail

/// `v` scaled down to `numerator` (0 <= numerator <= |v|: a limit that bites), direction kept,
/// `magnitude` being norm_of(v). A numerator past |v| leaves v as it is; a negative one gives 0.
/// In a Q format the factor numerator / |v| is a 32-bit fraction, one division
/// (detail::scaled_by_fraction). The factor is within 2^-32 of the ratio, so a component is
/// off the exactly rounded quotient only within |c| 2^-32 LSB of a tie. The ratio rounded to an
/// LSB instead would be a coarse factor when it is small (a 13 N step out of a 30000 N request
/// is a ratio of 29 LSB, 2% off), and safety limits scale by exactly such ratios. It divides by
/// the true norm (tick_fuzz found (8, 8, 8) out of an 8 N clamp when the saturated one was
/// used: up to sqrt(3) too long).
template <Scalar S>
constexpr Vec3<S> scale_to_norm(const Vec3<S>& v, S numerator, const NormOf<S>& magnitude) noexcept {
  if constexpr (kIsFixed<S>) {
    if (magnitude.root == 0 || numerator.raw() <= 0) return {};  // nothing to scale, or to nothing
    // numerator 2^32 / |v| < 2^32 when numerator < |v|; capped at 1 - 2^-32 otherwise, which
    // gives every component back as it is (|c| (2^32 - 1) / 2^32 rounds to |c|).
    const std::uint64_t quotient =
        detail::div_u64_u32(std::uint64_t{static_cast<std::uint32_t>(numerator.raw())} << 32, magnitude.root);
    return detail::scaled_by_fraction(v, (quotient >> 32) != 0 ? 0xFFFF'FFFFU : static_cast<std::uint32_t>(quotient));
  } else {
    return v * (numerator / magnitude.value);
  }
}

/// `v` scaled down to `limit`, direction kept, when |v| exceeds it (a negative limit counts as
/// 0), else nothing: every magnitude limit of the tick (the rate limit, the clamp, the
/// slippery law's). In a Q format the squares are compared exactly, as norm_if_above, and the
/// factor limit / |v| is limit times the inverse root of |v|^2 (detail::inverse_root): no root
/// and no division (they were about 125 instructions of a tick's bound per limit,
/// and four UDIVs). The factor is never above the ratio and within 2^-26 of it, so a component
/// is never past the exactly scaled one rounded to nearest, and under the exact one by at most
/// 2^-26 of it and half an LSB (at most one LSB under the rounded one below 512 N): the limit
/// holds but for the components' rounding.
template <Scalar S>
constexpr std::optional<Vec3<S>> scaled_if_above(const Vec3<S>& v, S limit) noexcept {
  if constexpr (kIsFixed<S>) {
    const std::uint64_t squares = detail::raw_squares(v);
    if (squares <= detail::raw_square(limit)) return std::nullopt;
    if (limit.raw() <= 0) return Vec3<S>{};
    const std::uint32_t factor =
        detail::times_inverse_root(static_cast<std::uint32_t>(limit.raw()), detail::inverse_root(squares));
    return detail::scaled_by_fraction(v, factor);
  } else {
    const auto magnitude = norm_if_above(v, limit);
    if (!magnitude) return std::nullopt;
    return scale_to_norm(v, limit, *magnitude);
  }
}

/// `v` times `k` where no product can leave the range: k a share in [0, 1] (the soft start's
/// gain), or v a unit vector (each component in [-1, 1]: a plane's normal) and k >= 0 (a
/// wall's push) or the negation of one (never lowest(), whose product with -1 would not fit).
/// Each product is then at most |c| or |k| in magnitude, so in a Q format it is rounded as
/// operator* rounds it, without the saturation test (three a vector).
template <Scalar S>
constexpr Vec3<S> times_in_range(const Vec3<S>& v, S k) noexcept {
  if constexpr (kIsFixed<S>) {
    using W = typename S::Wide;
    const auto times = [k](S c) { return S::from_product_in_range(W{c.raw()} * k.raw()); };
    return {times(v.x), times(v.y), times(v.z)};
  } else {
    return v * k;
  }
}

/// A unit vector `unit` (each component in [-1, 1]: a plane's normal) times any `k`, in a Q
/// format without the saturation test (three a vector): k = lowest() is taken as
/// -max() first, the one k whose product with a component of -1 would not fit. That changes
/// a product by at most one raw unit, and only for a k at the end of the range (a force that
/// saturated, or exactly -32,768 N in Q16.16). Floating point multiplies.
template <Scalar S>
constexpr Vec3<S> times_unit(const Vec3<S>& unit, S k) noexcept {
  if constexpr (kIsFixed<S>) {
    return times_in_range(unit, max(k, -S::max()));
  } else {
    return unit * k;
  }
}

/// a + b where no component can leave the range: b a step from a toward some c in range,
/// scaled down (each b_i of c_i - a_i's sign and at most its magnitude; c - a itself may have
/// saturated, toward the true difference), so a_i + b_i lies between a_i and c_i. In a Q
/// format the raw values add without the saturation test (three a vector).
template <Scalar S>
constexpr Vec3<S> plus_in_range(const Vec3<S>& a, const Vec3<S>& b) noexcept {
  if constexpr (kIsFixed<S>) {
    const auto plus = [](S p, S q) { return S::from_raw(static_cast<typename S::Raw>(p.raw() + q.raw())); };
    return {plus(a.x, b.x), plus(a.y, b.y), plus(a.z, b.z)};
  } else {
    return a + b;
  }
}

/// `v` scaled down, direction kept, so that its magnitude is at most `max_magnitude` (>= 0).
template <Scalar S>
constexpr Vec3<S> limit_magnitude(const Vec3<S>& v, S max_magnitude) noexcept {
  return scaled_if_above(v, max_magnitude).value_or(v);
}

/// The part of `v` perpendicular to the unit vector `n`: v - (n.v) n, with n.v already known
/// (a contact's normal speed: GCC cannot share a Q product between two calls, its saturation
/// test being an asm statement, so a second dot product would be computed again). (n.v) n is
/// times_unit's: a Q format skips the products' saturation tests.
template <Scalar S>
constexpr Vec3<S> tangential_part(const Vec3<S>& v, const Vec3<S>& n, S n_dot_v) noexcept {
  return v - times_unit(n, n_dot_v);
}
/// The same, computing n.v.
template <Scalar S>
constexpr Vec3<S> tangential_part(const Vec3<S>& v, const Vec3<S>& n) noexcept {
  return tangential_part(v, n, dot_unit(n, v));
}

}  // namespace toonforce
